//! What stands on the table outside the workspace comes back as obstacle
//! boxes when the request gives a region, and is never planned.

use mvgrasp_core::{GraspNet, MomentsNet, PlanOptions, Planner, PlannerConfig, Workspace};
use nalgebra::Vector3;

use crate::scene::{self, Camera, Scene, Shape, labelled_points};

#[test]
fn objects_outside_the_workspace_come_back_as_boxes_and_are_not_planned() {
    let z = 0.0;
    let scene = Scene {
        table_z: z,
        table_half: [0.6, 0.45],
        shapes: vec![
            // Inside the workspace: two objects to plan.
            Shape::standing_box(z, -0.05, 0.05, 0.3, [0.06, 0.04, 0.10]),
            Shape::upright_cylinder(z, 0.08, -0.06, 0.03, 0.08),
            // Outside it: a tall box and a lying cylinder.
            Shape::standing_box(z, 0.42, 0.15, 0.0, [0.06, 0.05, 0.18]),
            Shape::lying_cylinder(z, -0.40, -0.25, 0.7, 0.03, 0.14),
            // Across the workspace's border at x = 0.2: half in, half out.
            Shape::standing_box(z, 0.2, 0.1, 0.0, [0.08, 0.05, 0.07]),
        ],
    };
    let camera = Camera::orbit(Vector3::zeros(), 1.0, 60.0, -90.0);
    let rendered = scene::render(&scene, &camera);
    let bytes = rendered.depth_bytes();
    let workspace = Workspace::new([-0.2, -0.2, z - 0.05], [0.2, 0.2, z + 0.4]).expect("box");
    let input = camera.scene_input(&bytes, workspace);
    let mut net = MomentsNet::default();
    let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).expect("planner");

    // No region: nothing outside is looked at.
    let plain = planner
        .plan(&input, &PlanOptions::default(), &mut net)
        .expect("plan");
    assert!(plain.obstacles.is_empty() && plain.obstacles_dropped == 0);
    assert_eq!(plain.objects.len(), 3);

    let region = Workspace::new([-0.6, -0.45, z - 0.05], [0.6, 0.45, z + 0.5]).expect("box");
    let options = PlanOptions {
        obstacle_region: Some(region),
        ..PlanOptions::default()
    };
    let plan = planner.plan(&input, &options, &mut net).expect("plan");
    // The same objects and grasps: the obstacles change nothing planned.
    assert_eq!(plan.objects, plain.objects);
    assert_eq!(plan.grasps, plain.grasps);
    assert_eq!(
        (plan.obstacles.len(), plan.obstacles_dropped),
        (3, 0),
        "{:?}",
        plan.obstacles
    );
    // The rest of the object the border cuts is that object's, the others no one's.
    let cut = plan
        .objects
        .iter()
        .find(|o| (o.frame.world_from_object.translation.vector.x - 0.18).abs() < 0.03)
        .expect("the cut object, its inner half centred near x = 0.18");
    let continuing: Vec<_> = plan.obstacles.iter().filter(|o| o.object_id.is_some()).collect();
    assert_eq!(continuing.len(), 1, "{:?}", plan.obstacles);
    assert_eq!(continuing[0].object_id, Some(cut.id));
    assert!(
        continuing[0].min.x >= 0.19 && continuing[0].max.x < 0.26,
        "{:?}",
        continuing[0]
    );
    for (shape, height) in [(2u16, 0.18), (3, 0.06)] {
        let seen: Vec<_> = labelled_points(&rendered, &camera, 2 + shape)
            .into_iter()
            .filter(|p| p.z > z + 0.01)
            .collect();
        assert!(seen.len() > 100, "shape {shape}: {} points", seen.len());
        // One box holds every point seen of the shape (to 5 mm), from the
        // table up to the shape's top (to 5 mm), and stays outside the workspace.
        let boxed = plan
            .obstacles
            .iter()
            .find(|o| {
                seen.iter()
                    .all(|p| (0..3).all(|i| p[i] >= o.min[i] - 0.005 && p[i] <= o.max[i] + 0.005))
            })
            .unwrap_or_else(|| panic!("no box holds shape {shape}: {:?}", plan.obstacles));
        assert!(
            (boxed.max.z - (z + height)).abs() < 0.005,
            "shape {shape}: {boxed:?}"
        );
        assert!((boxed.min.z - z).abs() < 0.002, "shape {shape}: {boxed:?}");
        assert_eq!(boxed.object_id, None, "shape {shape}: {boxed:?}");
        let overlaps_workspace =
            (0..2).all(|i| boxed.min[i] < workspace.max[i] && boxed.max[i] > workspace.min[i]);
        assert!(!overlaps_workspace, "shape {shape}: {boxed:?}");
        // One object's box, not a merger with the table or its neighbours.
        let side = |i: usize| boxed.max[i] - boxed.min[i];
        assert!(side(0) < 0.2 && side(1) < 0.2, "shape {shape}: {boxed:?}");
    }

    // A region that holds nothing outside the workspace (the cut object's
    // outer half lies past x = 0.2): no box.
    let inner = Workspace::new([-0.3, -0.3, z - 0.05], [0.19, 0.3, z + 0.5]).expect("box");
    let options = PlanOptions {
        obstacle_region: Some(inner),
        ..PlanOptions::default()
    };
    let plan = planner.plan(&input, &options, &mut net).expect("plan");
    assert!(plan.obstacles.is_empty(), "{:?}", plan.obstacles);
}
