//! What stands on the table outside the workspace comes back as obstacle
//! boxes when the request gives a region, and is never planned.

use mvgrasp_core::{BodyCapsule, GraspNet, MomentsNet, Plan, PlanOptions, Planner, PlannerConfig, Workspace};
use nalgebra::Vector3;

use crate::scene::{self, Camera, Rendered, Scene, Shape, labelled_points};

/// `shapes` on a 1.2 x 0.9 m table at z = 0, seen from 1 m at 60 degrees,
/// planned in the 0.4 m square around the origin.
struct Cell {
    rendered: Rendered,
    camera: Camera,
    bytes: Vec<u8>,
    planner: Planner,
    net: MomentsNet,
}

impl Cell {
    fn new(shapes: Vec<Shape>) -> Self {
        let scene = Scene {
            table_z: 0.0,
            table_half: [0.6, 0.45],
            shapes,
        };
        let camera = Camera::orbit(Vector3::zeros(), 1.0, 60.0, -90.0);
        let rendered = scene::render(&scene, &camera);
        let bytes = rendered.depth_bytes();
        let net = MomentsNet::default();
        let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).expect("planner");
        Self {
            rendered,
            camera,
            bytes,
            planner,
            net,
        }
    }

    fn workspace() -> Workspace {
        Workspace::new([-0.2, -0.2, -0.05], [0.2, 0.2, 0.4]).expect("box")
    }

    /// The plan, with the boxes of what stands in `region` outside the workspace.
    fn plan(&mut self, region: Option<Workspace>) -> Plan {
        self.plan_with(PlanOptions {
            obstacle_region: region,
            ..PlanOptions::default()
        })
    }

    fn plan_with(&mut self, options: PlanOptions) -> Plan {
        let input = self.camera.scene_input(&self.bytes, Self::workspace());
        self.planner.plan(&input, &options, &mut self.net).expect("plan")
    }
}

/// The whole table.
fn table_region() -> Option<Workspace> {
    Some(Workspace::new([-0.6, -0.45, -0.05], [0.6, 0.45, 0.5]).expect("box"))
}

#[test]
fn objects_outside_the_workspace_come_back_as_boxes_and_are_not_planned() {
    let z = 0.0;
    let mut cell = Cell::new(vec![
        // Inside the workspace: two objects to plan.
        Shape::standing_box(z, -0.05, 0.05, 0.3, [0.06, 0.04, 0.10]),
        Shape::upright_cylinder(z, 0.08, -0.06, 0.03, 0.08),
        // Outside it: a tall box and a lying cylinder.
        Shape::standing_box(z, 0.42, 0.15, 0.0, [0.06, 0.05, 0.18]),
        Shape::lying_cylinder(z, -0.40, -0.25, 0.7, 0.03, 0.14),
        // Across the workspace's border at x = 0.2: half in, half out.
        Shape::standing_box(z, 0.2, 0.1, 0.0, [0.08, 0.05, 0.07]),
    ]);
    let workspace = Cell::workspace();

    // No region: nothing outside is looked at.
    let plain = cell.plan(None);
    assert!(plain.obstacles.is_empty() && plain.obstacles_dropped == 0);
    assert_eq!(plain.objects.len(), 3);

    let plan = cell.plan(table_region());
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
        let seen: Vec<_> = labelled_points(&cell.rendered, &cell.camera, 2 + shape)
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
    let plan = cell.plan(Some(inner));
    assert!(plan.obstacles.is_empty(), "{:?}", plan.obstacles);
}

#[test]
fn a_neighbour_against_the_rest_of_a_cut_object_is_an_obstacle_for_it_too() {
    let z = 0.0;
    let plan = Cell::new(vec![
        // Across the workspace's border at x = 0.2: 7 cm high, half in, half out.
        Shape::standing_box(z, 0.2, 0.1, 0.0, [0.08, 0.05, 0.07]),
        // Outside, 5 mm from its outer face: a box 16 cm high.
        Shape::standing_box(z, 0.275, 0.1, 0.0, [0.06, 0.05, 0.16]),
        // Outside, against nothing inside: a box 12 cm high by the border at y = -0.2.
        Shape::standing_box(z, 0.0, -0.235, 0.0, [0.06, 0.06, 0.12]),
        // Inside, its edge 1 cm from the border at y = -0.2: 3 cm high.
        Shape::standing_box(z, 0.0, -0.16, 0.0, [0.06, 0.06, 0.03]),
    ])
    .plan(table_region());
    assert_eq!(plan.objects.len(), 2, "{:?}", plan.objects);
    let cut = plan
        .objects
        .iter()
        .find(|o| (o.frame.world_from_object.translation.vector.x - 0.18).abs() < 0.03)
        .expect("the cut object, its inner half centred near x = 0.18");
    assert_eq!(plan.obstacles.len(), 3, "{:?}", plan.obstacles);
    // Each box by its top: the rest (7 cm) the cut object's, the two others no one's.
    for (top, owner) in [(0.07, Some(cut.id)), (0.16, None), (0.12, None)] {
        let boxed = plan
            .obstacles
            .iter()
            .find(|o| (o.max.z - top).abs() < 0.005)
            .unwrap_or_else(|| panic!("no box {top} m high: {:?}", plan.obstacles));
        assert_eq!(boxed.object_id, owner, "{boxed:?}");
    }
    let rest = plan
        .obstacles
        .iter()
        .find(|o| o.object_id.is_some())
        .expect("the rest");
    assert!(rest.max.x < 0.25, "the rest stops at the neighbour: {rest:?}");
}

#[test]
fn the_robots_body_is_neither_an_object_nor_an_obstacle() {
    let z = 0.0;
    let mut cell = Cell::new(vec![
        // Inside the workspace: an object to plan, and a link of the arm
        // coming down into it (a rod 25 cm high).
        Shape::standing_box(z, -0.05, 0.05, 0.3, [0.06, 0.04, 0.10]),
        Shape::upright_cylinder(z, 0.1, -0.1, 0.03, 0.25),
        // Outside: the arm's base column, and a cup beside it.
        Shape::upright_cylinder(z, 0.42, 0.15, 0.05, 0.18),
        Shape::upright_cylinder(z, 0.42, -0.15, 0.04, 0.10),
    ]);
    let capsule = |x: f64, y: f64, top: f64, radius: f64| {
        BodyCapsule::new(Vector3::new(x, y, z), Vector3::new(x, y, top), radius).expect("capsule")
    };
    let plain = cell.plan(table_region());
    assert_eq!(plain.objects.len(), 2, "{:?}", plain.objects);
    assert_eq!(plain.obstacles.len(), 2, "{:?}", plain.obstacles);

    let plan = cell.plan_with(PlanOptions {
        obstacle_region: table_region(),
        robot_body: vec![capsule(0.1, -0.1, 0.3, 0.05), capsule(0.42, 0.15, 0.2, 0.08)],
        ..PlanOptions::default()
    });
    // The box alone is planned, and the cup alone is an obstacle.
    assert_eq!(plan.objects.len(), 1, "{:?}", plan.objects);
    let centre = plan.objects[0].frame.world_from_object.translation.vector;
    assert!(
        (centre.x + 0.05).abs() < 0.03 && (centre.y - 0.05).abs() < 0.03,
        "{centre:?}"
    );
    assert!(plan.grasps.iter().all(|g| g.object_id == plan.objects[0].id));
    assert_eq!(plan.obstacles.len(), 1, "{:?}", plan.obstacles);
    let cup = &plan.obstacles[0];
    assert!(
        (cup.max.z - 0.10).abs() < 0.005 && cup.min.y < -0.15 && cup.max.y > -0.15,
        "{cup:?}"
    );

    // A body the checks refuse is a named error.
    let bad = PlanOptions {
        robot_body: vec![BodyCapsule {
            radius_m: f64::NAN,
            ..capsule(0.0, 0.0, 0.1, 0.05)
        }],
        ..PlanOptions::default()
    };
    let input = cell.camera.scene_input(&cell.bytes, Cell::workspace());
    let err = cell
        .planner
        .plan(&input, &bad, &mut cell.net)
        .unwrap_err()
        .to_string();
    assert!(err.contains("robot_body[0].radius_m"), "{err}");
}
