//! The knowledge service through the real app: bundled data on first start, places and robots,
//! map import (every shared ROS map), perceived objects, on-demand databases, and tokens.

use std::path::PathBuf;

use reqwest::Method;
use serde_json::{Value, json};

use crate::helpers::{spawn_app, url_encode};

fn shared_ros_maps() -> Option<Vec<PathBuf>> {
    let root = fixtures::shared_fixture("maps/ros", "the shared ROS maps")?;
    let mut yamls = Vec::new();
    for dir in std::fs::read_dir(&root).unwrap() {
        let dir = dir.unwrap().path();
        for file in std::fs::read_dir(&dir).unwrap() {
            let file = file.unwrap().path();
            if file.extension().is_some_and(|e| e == "yaml") {
                yamls.push(file);
            }
        }
    }
    yamls.sort();
    Some(yamls)
}

async fn import(
    app: &crate::helpers::TestApp,
    name: &str,
    yaml: &str,
    image: Vec<u8>,
) -> reqwest::Response {
    let form = reqwest::multipart::Form::new()
        .text("name", name.to_owned())
        .text("yaml", yaml.to_owned())
        .part(
            "image",
            reqwest::multipart::Part::bytes(image).file_name("map.pgm"),
        );
    app.request(Method::POST, "/v1/maps")
        .multipart(form)
        .send()
        .await
        .unwrap()
}

#[tokio::test]
async fn first_start_serves_the_bundled_building_and_robot() {
    let app = spawn_app().await;
    assert!(!app.token.is_empty(), "an admin token was created");
    let places: Vec<Value> = app
        .request(Method::GET, "/v1/places")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(
        places
            .iter()
            .any(|p| p["kind"] == "floor" && p["map"]["width"].as_u64().unwrap() > 0)
    );
    assert!(places.iter().any(|p| p["kind"] == "room"));
    let robots: Vec<Value> = app
        .request(Method::GET, "/v1/robots")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    // The paper's robot and the TIAGo-like base.
    assert_eq!(robots.len(), 2);
    let mut ids: Vec<&str> = robots.iter().filter_map(|r| r["id"].as_str()).collect();
    ids.sort_unstable();
    assert_eq!(ids, ["R-001", "TB-001"]);
    for id in ids {
        let robot = app
            .request(Method::GET, &format!("/v1/robots/{id}"))
            .send()
            .await
            .unwrap();
        assert_eq!(robot.status(), 200, "{id}");
    }

    let floor = places.iter().find(|p| p["kind"] == "floor").unwrap();
    let id = floor["id"].as_str().unwrap();
    let png = app
        .request(Method::GET, &format!("/v1/places/{id}/map.png"))
        .send()
        .await
        .unwrap();
    assert_eq!(png.status(), 200);
    assert_eq!(png.headers()["content-type"], "image/png");
    let bytes = png.bytes().await.unwrap();
    assert_eq!(&bytes[..4], b"\x89PNG");
    app.stop().await;
}

#[tokio::test]
async fn requests_without_a_valid_token_are_refused() {
    let app = spawn_app().await;
    let anonymous = app.get("/v1/places").await;
    assert_eq!(anonymous.status(), 401);
    let body: Value = anonymous.json().await.unwrap();
    assert_eq!(body["error"]["code"], "unauthorized");
    let wrong = app
        .client
        .get(format!("{}/sparql?query=ASK%7B%7D", app.address))
        .bearer_auth("nope")
        .send()
        .await
        .unwrap();
    assert_eq!(wrong.status(), 401);
    let ok = app
        .request(Method::GET, "/sparql?query=ASK%7B%7D")
        .send()
        .await
        .unwrap();
    assert_eq!(ok.status(), 200);
    app.stop().await;
}

#[tokio::test]
async fn every_shared_ros_map_imports_and_reads_back() {
    let Some(yamls) = shared_ros_maps() else {
        return;
    };
    let app = spawn_app().await;
    for yaml_path in &yamls {
        let yaml = std::fs::read_to_string(yaml_path).unwrap();
        let meta = tosm::RosMapMeta::parse_yaml(&yaml).unwrap();
        let image = std::fs::read(yaml_path.parent().unwrap().join(&meta.image)).unwrap();
        let name = yaml_path
            .parent()
            .unwrap()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .replace('.', "-");
        let response = import(&app, &name, &yaml, image).await;
        assert_eq!(
            response.status(),
            201,
            "{}: {}",
            yaml_path.display(),
            response.text().await.unwrap()
        );
        let body: Value = response.json().await.unwrap();
        assert!(body["free_area_m2"].as_f64().unwrap() > 10.0, "{body}");
        let floor = body["floor"].as_str().unwrap();
        let encoded: String = url_encode(floor);
        let place: Value = app
            .request(Method::GET, &format!("/v1/places/{encoded}"))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        assert_eq!(place["kind"], "floor", "{place}");
        // The import's name is the floor's identifier: requests may use it instead of the IRI.
        let by_name = app
            .request(Method::GET, &format!("/v1/places/{name}"))
            .send()
            .await
            .unwrap();
        assert_eq!(by_name.status(), 200, "{name}");
    }
    app.stop().await;
}

#[tokio::test]
async fn bad_maps_are_4xx_naming_the_problem() {
    /// A PNG declaring `w` × `h` grey pixels with no pixel data: signature, IHDR, an empty
    /// IDAT, IEND.
    fn png_header(w: u32, h: u32) -> Vec<u8> {
        fn crc32(bytes: &[u8]) -> u32 {
            let mut c = 0xffff_ffffu32;
            for &b in bytes {
                c ^= u32::from(b);
                for _ in 0..8 {
                    c = if c & 1 == 1 {
                        0xedb8_8320 ^ (c >> 1)
                    } else {
                        c >> 1
                    };
                }
            }
            !c
        }
        let chunk = |kind: &[u8], data: &[u8]| {
            let mut v = (data.len() as u32).to_be_bytes().to_vec();
            let mut body = kind.to_vec();
            body.extend_from_slice(data);
            v.extend_from_slice(&body);
            v.extend_from_slice(&crc32(&body).to_be_bytes());
            v
        };
        let mut ihdr = w.to_be_bytes().to_vec();
        ihdr.extend_from_slice(&h.to_be_bytes());
        ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        png.extend(chunk(b"IHDR", &ihdr));
        // An empty zlib stream: the pixels are not there, only the declared size.
        png.extend(chunk(
            b"IDAT",
            &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
        ));
        png.extend(chunk(b"IEND", &[]));
        png
    }
    let app = spawn_app().await;
    let good_yaml = "image: m.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
    let pgm = |w: usize, h: usize| {
        let mut v = format!("P5\n{w} {h}\n255\n").into_bytes();
        v.extend(std::iter::repeat_n(254u8, w * h));
        v
    };
    let cases = [
        (
            "malformed yaml",
            "resolution: [".to_owned(),
            pgm(8, 8),
            "yaml",
        ),
        (
            "negative resolution",
            good_yaml.replace("0.05", "-0.05"),
            pgm(8, 8),
            "resolution",
        ),
        (
            "truncated image",
            good_yaml.to_owned(),
            pgm(8, 8)[..20].to_vec(),
            "image",
        ),
        ("missing image", good_yaml.to_owned(), Vec::new(), "image"),
        (
            "overflowing resolution",
            good_yaml.replace("0.05", "1.0e306"),
            pgm(8, 8),
            "resolution",
        ),
        (
            "origin far away",
            good_yaml.replace("[0.0, 0.0, 0.0]", "[1.0e300, 0.0, 0.0]"),
            pgm(8, 8),
            "origin",
        ),
    ];
    for (what, yaml, image, needle) in cases {
        let response = import(&app, "bad", &yaml, image).await;
        let status = response.status();
        let body: Value = response.json().await.unwrap();
        assert!(status.is_client_error(), "{what}: {status} {body}");
        let message = body["error"]["message"].as_str().unwrap().to_lowercase();
        assert!(message.contains(needle), "{what}: {message}");
    }
    // Decompression bombs: a few bytes declaring 23,000 × 23,000 pixels are refused from
    // the header, before any pixel is decoded (413, naming the budget).
    let pgm_bomb = b"P5\n23000 23000\n255\n\xfe\xfe".to_vec();
    for (what, yaml, image) in [
        ("PGM", good_yaml.to_owned(), pgm_bomb),
        (
            "PNG",
            good_yaml.replace("m.pgm", "m.png"),
            png_header(23_000, 23_000),
        ),
    ] {
        let started = std::time::Instant::now();
        let response = import(&app, "bomb", &yaml, image).await;
        let status = response.status();
        let body: Value = response.json().await.unwrap();
        assert_eq!(status, 413, "{what}: {body}");
        let message = body["error"]["message"].as_str().unwrap();
        assert!(
            message.contains("23000x23000") && message.contains("pixels"),
            "{message}"
        );
        assert!(
            started.elapsed() < std::time::Duration::from_secs(5),
            "{what} took {:?}",
            started.elapsed()
        );
    }
    // A form without the image field at all.
    let form = reqwest::multipart::Form::new()
        .text("name", "x")
        .text("yaml", good_yaml);
    let response = app
        .request(Method::POST, "/v1/maps")
        .multipart(form)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 400);
    app.stop().await;
}

#[tokio::test]
async fn a_reported_object_appears_in_the_next_on_demand_database() {
    let app = spawn_app().await;
    let places: Vec<Value> = app
        .request(Method::GET, "/v1/places")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let room = places
        .iter()
        .find(|p| p["kind"] == "room" && !p["connected"].as_array().unwrap().is_empty())
        .unwrap();
    let room_iri = room["iri"].as_str().unwrap();
    let neighbour = room["connected"][0].as_str().unwrap();
    let boundary = room["boundary"].as_array().unwrap();
    let (mut cx, mut cy) = (0.0, 0.0);
    for p in boundary {
        cx += p[0].as_f64().unwrap();
        cy += p[1].as_f64().unwrap();
    }
    let n = boundary.len() as f64;
    let report = json!({
        "id": "vending-42",
        "class": "VendingMachine",
        "pose": {"x": cx / n, "y": cy / n, "yaw": 0.3},
        "shape": {"type": "box", "length": 0.8, "width": 0.7, "height": 1.8},
        "colour": {"r": 0.9, "g": 0.1, "b": 0.1}
    });
    let id = url_encode(room_iri);
    let created = app
        .request(Method::POST, &format!("/v1/places/{id}/objects"))
        .json(&report)
        .send()
        .await
        .unwrap();
    assert_eq!(created.status(), 201, "{}", created.text().await.unwrap());
    let again = app
        .request(Method::POST, &format!("/v1/places/{id}/objects"))
        .json(&report)
        .send()
        .await
        .unwrap();
    assert_eq!(again.status(), 200, "the same id updates");

    let mission =
        json!({"robot": "R-001", "start": {"place": room_iri}, "goals": [{"place": neighbour}]});
    let response = app
        .request(Method::POST, "/v1/on-demand")
        .header("accept", "application/n-triples")
        .json(&mission)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let count: usize = response.headers()["x-triple-count"]
        .to_str()
        .unwrap()
        .parse()
        .unwrap();
    let body = response.text().await.unwrap();
    assert_eq!(body.lines().filter(|l| !l.trim().is_empty()).count(), count);
    assert!(
        body.contains("objects/vending-42>"),
        "the reported object is included"
    );
    assert!(body.contains("VendingMachine"));
    assert!(body.contains("differential-robot"));
    assert_eq!(
        body.matches("objects/vending-42> <https://mentalsim.dev/ontology/tosm#hasShape>")
            .count(),
        1,
        "updated, not duplicated"
    );

    // Turtle and JSON-LD by Accept; something else is 406.
    for (accept, status) in [
        ("text/turtle", 200),
        ("application/ld+json", 200),
        ("image/gif", 406),
    ] {
        let r = app
            .request(Method::POST, "/v1/on-demand")
            .header("accept", accept)
            .json(&mission)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), status, "{accept}");
    }
    app.stop().await;
}

/// The floor database carries an ETag naming the graph's state: asked again with it, the
/// service answers 304 until something is written.
#[tokio::test]
async fn the_floor_database_is_revalidated_by_etag() {
    let app = spawn_app().await;
    let url = "/v1/places/F0/on-demand?robot=R-001";
    let get = |tag: Option<String>| {
        let mut r = app
            .request(Method::GET, url)
            .header("accept", "application/n-triples");
        if let Some(tag) = tag {
            r = r.header("if-none-match", tag);
        }
        r.send()
    };
    let first = get(None).await.unwrap();
    assert_eq!(first.status(), 200);
    let etag = first.headers()["etag"].to_str().unwrap().to_owned();
    assert!(etag.starts_with('"') && etag.ends_with('"'), "{etag}");
    let again = get(Some(etag.clone())).await.unwrap();
    assert_eq!(again.status(), 304);
    assert!(again.text().await.unwrap().is_empty());
    // Another representation has another tag.
    let turtle = app
        .request(Method::GET, url)
        .header("accept", "text/turtle")
        .header("if-none-match", &etag)
        .send()
        .await
        .unwrap();
    assert_eq!(turtle.status(), 200);

    app.report_box("F0", "etag-crate", (0.0, 0.0), 0.5).await;
    let changed = get(Some(etag.clone())).await.unwrap();
    assert_eq!(changed.status(), 200, "a write changes the tag");
    assert_ne!(changed.headers()["etag"].to_str().unwrap(), etag);
    assert!(changed.text().await.unwrap().contains("etag-crate"));
    app.stop().await;
}

#[tokio::test]
async fn impossible_missions_are_distinct_4xx() {
    let app = spawn_app().await;
    let places: Vec<Value> = app
        .request(Method::GET, "/v1/places")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let room = places.iter().find(|p| p["kind"] == "room").unwrap()["iri"]
        .as_str()
        .unwrap()
        .to_owned();
    let cases = [
        (
            json!({"robot": "R-404", "start": {"place": room}, "goals": [{"place": room}]}),
            404,
            "unknown robot",
        ),
        (
            json!({"robot": "R-001", "start": {"x": 5000.0, "y": 5000.0}, "goals": [{"place": room}]}),
            422,
            "outside every known place",
        ),
        (
            json!({"robot": "R-001", "start": {"place": room}, "goals": []}),
            400,
            "no goals",
        ),
        (
            json!({"robot": "R-001", "start": {"place": room, "x": 1.0}, "goals": [{"place": room}]}),
            400,
            "either",
        ),
        (
            json!({"robot": "R-001", "start": {"place": "nowhere"}, "goals": [{"place": room}]}),
            404,
            "unknown place",
        ),
        (
            json!({"robot": "R-001", "start": {"place": room}}),
            422,
            "goals",
        ),
    ];
    for (mission, status, needle) in cases {
        let response = app
            .request(Method::POST, "/v1/on-demand")
            .json(&mission)
            .send()
            .await
            .unwrap();
        assert_eq!(response.status(), status, "{mission}");
        let body: Value = response.json().await.unwrap();
        let message = body["error"]["message"].as_str().unwrap();
        assert!(message.contains(needle), "{needle}: {message}");
    }
    // Rooms on the two floors of the sample building are not linked.
    let floors: Vec<&Value> = places.iter().filter(|p| p["kind"] == "floor").collect();
    let on = |floor: &Value| -> String {
        let f = floor["iri"].as_str().unwrap();
        places
            .iter()
            .find(|p| p["parent"] == f && p["kind"] != "floor")
            .unwrap()["iri"]
            .as_str()
            .unwrap()
            .to_owned()
    };
    let (a, b) = (on(floors[0]), on(floors[1]));
    let response = app
        .request(Method::POST, "/v1/on-demand")
        .json(&json!({"robot": "R-001", "start": {"place": a}, "goals": [{"place": b}]}))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 422);
    let body: Value = response.json().await.unwrap();
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("not connected")
    );
    app.stop().await;
}

#[tokio::test]
async fn a_floor_exports_as_sdf_and_the_robot_as_urdf_that_check_urdf_accepts() {
    let app = spawn_app().await;
    let places: Vec<Value> = app
        .request(Method::GET, "/v1/places")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let room = places.iter().find(|p| p["kind"] == "room").unwrap();
    let id = url_encode(room["iri"].as_str().unwrap());
    let sdf = app
        .request(Method::GET, &format!("/v1/places/{id}/world.sdf"))
        .send()
        .await
        .unwrap();
    assert_eq!(sdf.status(), 200);
    let sdf = sdf.text().await.unwrap();
    assert!(
        sdf.contains("<sdf version=\"1.9\">"),
        "{}",
        &sdf[..200.min(sdf.len())]
    );
    assert!(sdf.contains("<world"));
    // No robot unless asked where; with x and y the gz-sim model stands there.
    assert!(!sdf.contains("gz-sim-diff-drive-system"));
    let placed = app
        .request(
            Method::GET,
            &format!("/v1/places/{id}/world.sdf?x=0.5&y=-2&yaw=1.5"),
        )
        .send()
        .await
        .unwrap();
    assert_eq!(placed.status(), 200);
    let placed = placed.text().await.unwrap();
    assert!(placed.contains("gz-sim-diff-drive-system") && placed.contains("<pose>0.5 -2 "));
    for half in ["x=1", "y=1", "yaw=1", "x=1&y=NaN"] {
        let r = app
            .request(Method::GET, &format!("/v1/places/{id}/world.sdf?{half}"))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 400, "{half}");
    }
    // A building is on no floor: 404 naming it.
    let building = places.iter().find(|p| p["kind"] == "building").unwrap();
    let r = app
        .request(
            Method::GET,
            &format!(
                "/v1/places/{}/world.sdf",
                url_encode(building["iri"].as_str().unwrap())
            ),
        )
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
    let message = r.text().await.unwrap();
    assert!(
        message.contains(building["iri"].as_str().unwrap()),
        "{message}"
    );

    let urdf = app
        .request(Method::GET, "/v1/robots/R-001/robot.urdf")
        .send()
        .await
        .unwrap();
    assert_eq!(urdf.status(), 200);
    let urdf = urdf.text().await.unwrap();
    assert!(urdf.contains("<robot"));
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("robot.urdf");
    std::fs::write(&file, &urdf).unwrap();
    match std::process::Command::new("check_urdf").arg(&file).output() {
        Ok(out) => assert!(
            out.status.success(),
            "check_urdf: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(_) => fixtures::missing("check_urdf (Debian liburdfdom-tools)"),
    }
    let missing = app
        .request(Method::GET, "/v1/robots/R-404/robot.urdf")
        .send()
        .await
        .unwrap();
    assert_eq!(missing.status(), 404);
    app.stop().await;
}

/// The robot's gz-sim model and its ros_gz_bridge configuration: the same topics on both
/// sides, the clock of the world `world.sdf` names, 404 for an unknown robot.
#[tokio::test]
async fn the_robot_exports_as_a_gz_sim_model_and_a_bridge_configuration() {
    let app = spawn_app().await;
    let get = |path: String| {
        let request = app.request(Method::GET, &path);
        async move { request.send().await.unwrap() }
    };
    let sdf = get("/v1/robots/R-001/robot.sdf".into()).await;
    assert_eq!(sdf.status(), 200);
    assert_eq!(sdf.headers()["content-type"], "application/xml");
    let sdf = sdf.text().await.unwrap();
    assert!(sdf.contains("<sdf version=\"1.9\">"), "{sdf}");
    assert!(
        sdf.contains(r#"<model name="differential-robot">"#),
        "{sdf}"
    );
    assert!(
        sdf.contains(r#"filename="gz-sim-diff-drive-system""#),
        "{sdf}"
    );
    assert!(sdf.contains(r#"type="gpu_lidar""#), "{sdf}");

    let world = get("/v1/places/F0/world.sdf".into())
        .await
        .text()
        .await
        .unwrap();
    let name = world
        .split("<world name=\"")
        .nth(1)
        .and_then(|rest| rest.split('"').next())
        .expect("the world's name")
        .to_owned();
    assert!(
        world.contains("<render_engine>ogre2</render_engine>"),
        "{world}"
    );
    let bridge = get(format!("/v1/robots/R-001/bridge.yaml?world={name}")).await;
    assert_eq!(bridge.status(), 200);
    assert_eq!(bridge.headers()["content-type"], "application/yaml");
    let bridge = bridge.text().await.unwrap();
    // Each entry's Gazebo topic is one the model's systems and sensors use.
    for (ros, gz) in [
        ("/cmd_vel", "/model/differential-robot/cmd_vel"),
        ("/odom", "/model/differential-robot/odometry"),
        ("/scan", "/model/differential-robot/scan"),
        ("/tf", "/model/differential-robot/tf"),
        ("/joint_states", "/model/differential-robot/joint_states"),
        ("/clock", &format!("/world/{name}/clock")),
    ] {
        let entry = format!("- ros_topic_name: \"{ros}\"\n  gz_topic_name: \"{gz}\"\n");
        assert!(bridge.contains(&entry), "{entry} in {bridge}");
        if gz.starts_with("/model/") {
            assert!(sdf.contains(&format!(">{gz}<")), "{gz} in the model");
        }
    }
    assert!(bridge.contains("direction: ROS_TO_GZ"), "{bridge}");
    let global = get("/v1/robots/R-001/bridge.yaml".into())
        .await
        .text()
        .await
        .unwrap();
    assert!(
        global.contains("- ros_topic_name: \"/clock\"\n  gz_topic_name: \"/clock\"\n"),
        "{global}"
    );
    let bad = get("/v1/robots/R-001/bridge.yaml?world=a%20b".into()).await;
    assert_eq!(bad.status(), 400);
    for path in ["robot.sdf", "bridge.yaml"] {
        let missing = get(format!("/v1/robots/R-404/{path}")).await;
        assert_eq!(missing.status(), 404, "{path}");
    }
    app.stop().await;
}

/// A worker's HTTP knowledge source keeps the floor database (and so its world) while the
/// service answers 304, and reads it again after a write.
#[tokio::test]
async fn the_http_knowledge_source_reuses_its_database_until_a_write() {
    use jobs::source::{HttpKnowledge, KnowledgeSource};
    let app = spawn_app().await;
    let source = HttpKnowledge::new(&app.address, Some(app.token.clone())).unwrap();
    let first = source.floor_database("F0", "R-001").await.unwrap();
    let second = source.floor_database("F0", "R-001").await.unwrap();
    assert!(
        std::sync::Arc::ptr_eq(&first, &second),
        "revalidated, not read again"
    );
    app.report_box("F0", "source-crate", (0.0, 0.0), 0.5).await;
    let third = source.floor_database("F0", "R-001").await.unwrap();
    assert!(!std::sync::Arc::ptr_eq(&first, &third));
    assert_ne!(first.version, third.version);
    assert!(
        third
            .graph
            .iter()
            .any(|t| t.subject.to_string().contains("source-crate"))
    );
    assert!(third.graph.len() > first.graph.len());
    app.stop().await;
}

#[tokio::test]
async fn every_shared_map_exports_as_map_server_files_that_import_to_the_same_grid() {
    let Some(yamls) = shared_ros_maps() else {
        return;
    };
    let app = spawn_app().await;
    let get = |path: String| {
        let request = app.request(Method::GET, &path);
        async move {
            let r = request.send().await.unwrap();
            assert_eq!(r.status(), 200, "{path}");
            r.bytes().await.unwrap().to_vec()
        }
    };
    for (i, yaml_path) in yamls.iter().enumerate() {
        let yaml = std::fs::read_to_string(yaml_path).unwrap();
        let meta = tosm::RosMapMeta::parse_yaml(&yaml).unwrap();
        let image = std::fs::read(yaml_path.parent().unwrap().join(&meta.image)).unwrap();
        let (a, b) = (format!("round-trip-a-{i}"), format!("round-trip-b-{i}"));
        assert_eq!(import(&app, &a, &yaml, image).await.status(), 201);
        let yaml1 = String::from_utf8(get(format!("/v1/places/{a}/map.yaml")).await).unwrap();
        let pgm1 = get(format!("/v1/places/{a}/map.pgm")).await;
        assert!(pgm1.starts_with(b"P5\n"), "{}", yaml_path.display());
        // The exported pair imports as nav2's map_server reads it, to the same grid.
        let exported = tosm::RosMapMeta::parse_yaml(&yaml1).unwrap();
        assert_eq!(exported.image, "map.pgm");
        assert_eq!(
            exported.resolution,
            meta.resolution,
            "{}",
            yaml_path.display()
        );
        assert_eq!(exported.origin, meta.origin, "{}", yaml_path.display());
        assert_eq!(import(&app, &b, &yaml1, pgm1.clone()).await.status(), 201);
        let yaml2 = String::from_utf8(get(format!("/v1/places/{b}/map.yaml")).await).unwrap();
        let pgm2 = get(format!("/v1/places/{b}/map.pgm")).await;
        assert_eq!(yaml1, yaml2, "{}", yaml_path.display());
        assert!(pgm1 == pgm2, "{}: the grids differ", yaml_path.display());
        assert!(
            get(format!("/v1/places/{a}/map.png")).await
                == get(format!("/v1/places/{b}/map.png")).await,
            "{}",
            yaml_path.display()
        );
    }
    // A building is on no floor: 404 naming it.
    let places: Vec<Value> = app
        .request(Method::GET, "/v1/places")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let building = places.iter().find(|p| p["kind"] == "building").unwrap();
    let id = building["id"].as_str().unwrap();
    let r = app
        .request(Method::GET, &format!("/v1/places/{id}/map.yaml"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
    let body: Value = r.json().await.unwrap();
    let message = body["error"]["message"].as_str().unwrap();
    assert!(message.contains("on no floor"), "{message}");
    assert!(
        message.contains(building["iri"].as_str().unwrap()),
        "{message}"
    );
}
