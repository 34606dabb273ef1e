//! Snapshots: grasps and detections drawn where the camera sees them, detection overlap.

use super::*;

#[test]
fn snapshots_draw_a_grasp_where_the_camera_sees_it() {
    use mvgrasp_sim::files::write_grasp_snapshot;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    let table_z = 0.3;
    let scene = Scene {
        table_z,
        table_half: [0.6, 0.5],
        objects: Vec::new(),
        scenario: Scenario::Isolated,
        seed: 0,
    };
    let frame = render(&scene, &top_down(table_z, 1.0), None);
    let path = std::env::temp_dir().join(format!("mvgrasp-snapshot-{}.png", std::process::id()));
    // A 10 cm grasp on the table centre, closing along world x: seen from
    // 1 m above at 600 px focal length, its fingers are 60 px apart.
    let grasp = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, f64::from(table_z)),
        UnitQuaternion::identity(),
    );
    write_grasp_snapshot(&path, &frame, &[(grasp, 0.10, true)]).unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut rgb = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut rgb).unwrap();
    let at = |x: usize, y: usize| &rgb[3 * (y * 640 + x)..3 * (y * 640 + x) + 3];
    let green = [40u8, 230, 60];
    let (cx, cy) = (320usize, 240usize);
    let greens: Vec<usize> = (0..640)
        .filter(|&x| at(x, cy) == green || at(x, cy - 1) == green)
        .collect();
    assert!(!greens.is_empty(), "no grasp drawn on the centre row");
    let span = greens.last().unwrap() - greens.first().unwrap();
    assert!(
        (60..=70).contains(&span),
        "fingers {span} px apart, expected about 60 (+ the end dots)"
    );
    assert!(greens.first().unwrap().abs_diff(cx - 30) <= 4);
    assert_eq!(
        at(100, 100),
        at(540, 380),
        "the table stays grey away from the grasp"
    );
    let _ = std::fs::remove_file(&path);
}

#[test]
fn detections_are_drawn_beside_the_labels() {
    use mvgrasp_core::{Segmentation, TablePlane};
    use mvgrasp_sim::camera::Frame;
    use mvgrasp_sim::files::write_detections;

    let (w, h) = (640usize, 480usize);
    // A flat frame 1 m away; object 0 (label 2) fills a 20 px square at
    // (100, 100), one reading is lost; one detection covers the square's
    // left half.
    let mut frame = Frame {
        camera: top_down(0.0, 1.0),
        depth_mm: vec![1000; w * h],
        labels: vec![1; w * h],
    };
    let square: Vec<usize> = (100..120)
        .flat_map(|y| (100..120).map(move |x| y * w + x))
        .collect();
    for &i in &square {
        frame.labels[i] = 2;
    }
    frame.depth_mm[300 * w + 300] = 0;
    let left: Vec<u32> = square
        .iter()
        .filter(|&&i| i % w < 110)
        .map(|&i| i as u32)
        .collect();
    let seg = Segmentation {
        table: TablePlane {
            normal: Vector3::z(),
            offset_m: 0.0,
            support: 1.0,
        },
        points: vec![[0.0; 3]; left.len()],
        clusters: vec![(0..left.len() as u32).collect()],
        pixels: left,
    };
    let path = std::env::temp_dir().join(format!("mvgrasp-detections-{}.png", std::process::id()));
    write_detections(&path, &frame, &[&seg]).unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    assert_eq!(
        (reader.info().width, reader.info().height),
        (2 * w as u32, h as u32)
    );
    let mut rgb = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut rgb).unwrap();
    let at = |panel: usize, x: usize, y: usize| {
        let i = 3 * (y * 2 * w + panel * w + x);
        [rgb[i], rgb[i + 1], rgb[i + 2]]
    };
    let grey = at(0, 50, 50);
    assert_eq!(grey[0], grey[1]);
    assert_eq!(grey, at(1, 50, 50), "the table is grey in both panels");
    assert_eq!(at(0, 300, 300), [0, 0, 0], "a lost reading is black");
    // Labels: the whole square in one colour.
    assert_ne!(at(0, 105, 105), grey);
    assert_eq!(at(0, 105, 105), at(0, 115, 115));
    // Detections: the left half in its own colour, the right half grey.
    assert_ne!(at(1, 105, 105), grey);
    assert_ne!(at(1, 105, 105), at(0, 105, 105));
    assert_eq!(at(1, 115, 115), grey);
    let _ = std::fs::remove_file(&path);
}

#[test]
fn overlap_counts_merged_detections_and_split_objects() {
    use mvgrasp_core::{Segmentation, TablePlane};
    use mvgrasp_sim::camera::Frame;
    use mvgrasp_sim::overlap::Overlap;

    // Ten pixels of object 0 (label 2), ten of object 1 (label 3), one of
    // the table; every pixel a kept point.
    let labels: Vec<u16> = [vec![2; 10], vec![3; 10], vec![1]].concat();
    let frame = Frame {
        camera: top_down(0.0, 1.0),
        depth_mm: vec![1000; labels.len()],
        labels,
    };
    let seg = |clusters: Vec<Vec<u32>>| Segmentation {
        table: TablePlane {
            normal: Vector3::z(),
            offset_m: 0.0,
            support: 1.0,
        },
        points: vec![[0.0; 3]; 21],
        pixels: (0..21).collect(),
        clusters,
    };
    // Detection 0: object 0's first 5 pixels and all of object 1 (merged);
    // detection 1: object 0's other 5 and the table pixel. Object 0 is split.
    let o = Overlap::new(
        &frame,
        &seg(vec![
            (0..5).chain(10..20).collect(),
            (5..10).chain(20..21).collect(),
        ]),
    );
    assert_eq!(o.of_label[&2], 10);
    assert_eq!(o.of_detection, vec![15, 5], "the table pixel does not count");
    assert_eq!(o.merged(), 1);
    assert!(o.is_split(2));
    assert!(!o.is_split(3));
    // Object 0 in one detection with a pixel of object 1 (under 20%), object 1's
    // other nine unclustered: nothing merged or split, and object 1 still has
    // its ten kept pixels.
    let o = Overlap::new(&frame, &seg(vec![(0..11).collect()]));
    assert_eq!(o.merged(), 0);
    assert!(!o.is_split(2) && !o.is_split(3));
    assert_eq!(o.of_label[&3], 10);
    let mut shares = o.shares(3);
    shares.sort();
    assert_eq!(shares, vec![(0, 1)]);
}
