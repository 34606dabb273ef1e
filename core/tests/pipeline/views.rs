//! Which views an object is planned from: the view cascade, the
//! approach cone and the arm's reach.

use mvgrasp_core::{Channel, GraspNet, MomentsNet, PlanOptions, PlannerConfig, ViewPolicy, approach_of};
use nalgebra::Vector3;

use crate::scene::{Camera, Scene, grid_scene};
use crate::{plan_rendered, plan_rendered_by};

/// The analytic baseline with its maps edited after each call: `edit`
/// gets the call's number (1-based), the contract and the maps.
struct EditedNet<F> {
    net: MomentsNet,
    calls: usize,
    edit: F,
}

impl<F: FnMut(usize, &mvgrasp_core::ModelContract, &mut mvgrasp_core::GraspMaps)> EditedNet<F> {
    fn new(edit: F) -> Self {
        Self {
            net: MomentsNet::default(),
            calls: 0,
            edit,
        }
    }
}

impl<F: FnMut(usize, &mvgrasp_core::ModelContract, &mut mvgrasp_core::GraspMaps)> GraspNet for EditedNet<F> {
    fn contract(&self) -> &mvgrasp_core::ModelContract {
        self.net.contract()
    }

    fn infer(&mut self, batch: &mvgrasp_core::ViewBatch) -> mvgrasp_core::Result<mvgrasp_core::GraspMaps> {
        self.calls += 1;
        let mut maps = self.net.infer(batch)?;
        (self.edit)(self.calls, self.net.contract(), &mut maps);
        Ok(maps)
    }
}

/// A network that answers nothing on its first call, then as the analytic
/// baseline: what a chosen view without a usable grasp looks like.
fn silent_first(call: usize, _: &mvgrasp_core::ModelContract, maps: &mut mvgrasp_core::GraspMaps) {
    if call == 1 {
        maps.data.iter_mut().for_each(|v| *v = 0.0);
    }
}

/// Every opening predicted 16 cm wide, beyond the 14 cm stroke.
fn openings_16_cm(_: usize, contract: &mvgrasp_core::ModelContract, maps: &mut mvgrasp_core::GraspMaps) {
    let (channel, per_view) = (
        contract.channel_index(Channel::Width),
        maps.size_px * maps.size_px,
    );
    let scaled = 0.16 / contract.width_scale_m;
    for view in maps.data.chunks_exact_mut(4 * per_view) {
        view[channel * per_view..(channel + 1) * per_view].fill(scaled);
    }
}

/// Peaks whose predicted opening is wider than the stroke are counted per
/// object (`too_wide`) after every view was tried; within
/// `wide_slack_m` they are decoded at the full stroke and the hand check
/// keeps those whose pads clear the objects (16 cm apart).
#[test]
fn openings_wider_than_the_stroke_are_counted_or_left_to_the_hand_check() {
    let scene = grid_scene(0.1, 5, 5, 0.16);
    let camera = Camera::orbit(Vector3::new(0.0, 0.0, 0.1), 0.8, 50.0, -90.0);
    let options = PlanOptions {
        max_grasps: 50,
        min_quality: 0.0,
        ..PlanOptions::default()
    };
    for (slack, expect_grasps) in [(0.0, false), (0.03, true)] {
        let mut config = PlannerConfig::default();
        config.decode.wide_slack_m = slack;
        let (plan, _) = plan_rendered_by(
            config,
            &scene,
            &camera,
            &options,
            &mut EditedNet::new(openings_16_cm),
        );
        assert_eq!(plan.objects.len(), 5);
        for object in &plan.objects {
            let has_grasp = plan.grasps.iter().any(|g| g.object_id == object.id);
            assert_eq!(has_grasp, expect_grasps, "slack {slack}: object {}", object.id);
            if expect_grasps {
                assert_eq!(object.refused.too_wide, 0, "object {}", object.id);
            } else {
                assert!(
                    object.refused.too_wide > 0,
                    "object {}: {:?}",
                    object.id,
                    object.refused
                );
                assert!(object.views.iter().all(|v| v.inferred), "object {}", object.id);
            }
        }
        let widest = plan.grasps.iter().map(|g| g.width_m).fold(0.0, f64::max);
        assert!(widest <= mvgrasp_core::Gripper::default().max_width_m + 1e-9);
    }
}

/// An object whose chosen view gives no grasp goes on to its next view by
/// entropy; with the cascade off (the paper's single pass) it gets none.
#[test]
fn the_view_cascade_tries_the_next_view() {
    let scene = grid_scene(0.1, 5, 5, 0.12);
    let camera = Camera::orbit(Vector3::new(0.0, 0.0, 0.1), 0.8, 50.0, -90.0);
    for cascade in [true, false] {
        let mut net = EditedNet::new(silent_first);
        let options = PlanOptions {
            view_policy: ViewPolicy::Entropy,
            max_grasps: 50,
            min_quality: 0.1,
            view_cascade: cascade,
            ..PlanOptions::default()
        };
        let (plan, _) = plan_rendered_by(PlannerConfig::default(), &scene, &camera, &options, &mut net);
        assert_eq!(plan.objects.len(), 5);
        if cascade {
            assert!(net.calls >= 2, "a second round was inferred");
            assert!(!plan.grasps.is_empty());
            for object in &plan.objects {
                let inferred: Vec<_> = object.views.iter().filter(|v| v.inferred).collect();
                assert!(
                    inferred.len() >= 2,
                    "object {}: the next view was tried",
                    object.id
                );
                // Views go in entropy order, and only while the object has no grasp.
                let best_left = object
                    .views
                    .iter()
                    .filter(|v| !v.inferred)
                    .map(|v| v.entropy)
                    .fold(f64::NEG_INFINITY, f64::max);
                assert!(inferred.iter().all(|v| v.entropy >= best_left));
                let has_grasp = plan.grasps.iter().any(|g| g.object_id == object.id);
                assert!(
                    has_grasp || inferred.len() == 3,
                    "object {}: stopped without a grasp",
                    object.id
                );
            }
        } else {
            assert_eq!(net.calls, 1);
            assert!(plan.grasps.is_empty());
            for object in &plan.objects {
                assert_eq!(object.views.iter().filter(|v| v.inferred).count(), 1);
            }
        }
    }
}

/// Five boxes in a row seen from 50 degrees, and a request for every view
/// of each, up to 50 grasps of quality 0.1 or more.
fn five_in_a_row() -> (Scene, Camera, PlanOptions) {
    let every = PlanOptions {
        view_policy: ViewPolicy::All,
        max_grasps: 50,
        min_quality: 0.1,
        ..PlanOptions::default()
    };
    (
        grid_scene(0.1, 5, 5, 0.12),
        Camera::orbit(Vector3::new(0.0, 0.0, 0.1), 0.8, 50.0, -90.0),
        every,
    )
}

/// An approach cone keeps only the grasps within it: the views whose
/// direction lies outside it are not inferred (none of their grasps could
/// pass), and each object gets a grasp from the views within it. A cone
/// that no view lies within plans every object as without it, and counts
/// each grasp as outside the cone: every object has its reason.
#[test]
fn an_approach_cone_keeps_only_the_approaches_within_it() {
    let (scene, camera, every) = five_in_a_row();
    let (free, _) = plan_rendered(&scene, &camera, &every);
    assert_eq!(free.outside_approach_cone, 0);
    assert!(
        free.objects.iter().all(|o| o.views.iter().all(|v| v.inferred)),
        "no cone: every view"
    );
    let from_above =
        mvgrasp_core::ApproachCone::new(Vector3::new(0.0, 0.0, -2.0), 30f64.to_radians()).unwrap();
    for policy in [
        ViewPolicy::All,
        ViewPolicy::Entropy,
        ViewPolicy::Random { seed: 3 },
    ] {
        let options = PlanOptions {
            view_policy: policy,
            approach_cone: Some(from_above),
            ..every.clone()
        };
        let (plan, _) = plan_rendered(&scene, &camera, &options);
        assert_eq!(
            plan.outside_approach_cone, 0,
            "{policy:?}: no view outside was inferred"
        );
        for g in &plan.grasps {
            assert!(
                approach_of(g).z <= -(30f64.to_radians().cos()) + 1e-9,
                "{policy:?}"
            );
        }
        for object in &plan.objects {
            for view in &object.views {
                assert_eq!(
                    view.inferred,
                    view.axis == mvgrasp_core::ViewAxis::Top,
                    "{policy:?}: object {} {:?}",
                    object.id,
                    view.axis
                );
            }
            assert!(
                plan.grasps.iter().any(|g| g.object_id == object.id),
                "{policy:?}: object {} has no grasp from above",
                object.id
            );
        }
    }
    let from_below = mvgrasp_core::ApproachCone::new(Vector3::z(), 30f64.to_radians()).unwrap();
    for policy in [ViewPolicy::All, ViewPolicy::Entropy] {
        let options = PlanOptions {
            view_policy: policy,
            approach_cone: Some(from_below),
            ..every.clone()
        };
        let (plan, _) = plan_rendered(&scene, &camera, &options);
        assert!(plan.grasps.is_empty(), "{policy:?}");
        assert!(plan.outside_approach_cone > 0, "{policy:?}");
        // Each object accounts for its own losses; they add up to the plan's.
        let sum = |f: fn(&mvgrasp_core::ObjectRefusals) -> usize| -> usize {
            plan.objects.iter().map(|o| f(&o.refused)).sum()
        };
        assert_eq!(sum(|r| r.outside_approach_cone), plan.outside_approach_cone);
        assert_eq!(
            sum(|r| r.table + r.neighbour + r.own_points),
            plan.refused_for_collision
        );
        assert_eq!(sum(|r| r.table), plan.refusals.table);
        for object in &plan.objects {
            assert!(
                object.refused.outside_approach_cone > 0,
                "{policy:?}: object {}",
                object.id
            );
            assert!(
                object.views.iter().all(|v| v.inferred),
                "{policy:?}: every view tried"
            );
        }
    }
    assert!(mvgrasp_core::ApproachCone::new(Vector3::zeros(), 1.0).is_err());
    assert!(mvgrasp_core::ApproachCone::new(Vector3::z(), 0.0).is_err());
    assert!(mvgrasp_core::ApproachCone::new(Vector3::z(), 3.2).is_err());
    assert!(mvgrasp_core::ApproachCone::new(Vector3::z(), std::f64::consts::PI).is_ok());
}

/// An arm's reach keeps only the grasps it reaches, before ranking: an arm
/// high over the table reaches down onto the objects but not round their
/// sides, so side grasps are counted out of reach and, under the cascade,
/// each object goes on to a view the arm reaches. An arm that reaches
/// nothing leaves every object without a grasp, each with its reason, after
/// every view was tried.
#[test]
fn an_arm_reach_keeps_only_the_grasps_it_reaches() {
    let (scene, camera, every) = five_in_a_row();
    let overhead =
        mvgrasp_core::ArmReach::new(Vector3::new(0.0, 0.0, 0.9), Vector3::z(), 0.3, 0.1, 0.65, 0.0)
            .expect("reach");
    let (free, _) = plan_rendered(&scene, &camera, &every);
    assert_eq!(free.out_of_reach, 0);
    for policy in [ViewPolicy::All, ViewPolicy::Entropy] {
        let options = PlanOptions {
            view_policy: policy,
            arm_reach: Some(overhead),
            ..every.clone()
        };
        let (plan, _) = plan_rendered(&scene, &camera, &options);
        for g in &plan.grasps {
            assert!(
                overhead.reaches(&g.world_from_grasp.translation.vector, &approach_of(g)),
                "{policy:?}: {g:?}"
            );
            assert!(approach_of(g).z < -0.5, "{policy:?}: from above only");
        }
        let counted: usize = plan.objects.iter().map(|o| o.refused.out_of_reach).sum();
        assert_eq!(counted, plan.out_of_reach, "{policy:?}");
        if policy == ViewPolicy::All {
            assert!(plan.out_of_reach > 0, "the side views' grasps were dropped");
        }
        for object in &plan.objects {
            assert!(
                plan.grasps.iter().any(|g| g.object_id == object.id),
                "{policy:?}: object {} has a grasp the arm reaches",
                object.id
            );
        }
    }
    let far = mvgrasp_core::ArmReach::new(Vector3::new(3.0, 0.0, 0.2), Vector3::z(), 0.3, 0.1, 0.9, 0.1)
        .expect("reach");
    let options = PlanOptions {
        view_policy: ViewPolicy::Entropy,
        arm_reach: Some(far),
        ..every.clone()
    };
    let (plan, _) = plan_rendered(&scene, &camera, &options);
    assert!(plan.grasps.is_empty());
    for object in &plan.objects {
        assert!(object.refused.out_of_reach > 0, "object {}", object.id);
        assert!(
            object.views.iter().all(|v| v.inferred),
            "object {}: every view tried",
            object.id
        );
    }
}

/// The oblique views, when a planner renders them, give grasps that
/// approach 45 degrees off straight down from the side the camera saw:
/// inside a 50-degree cone about straight down that no front or side
/// view's grasp lies within.
#[test]
fn oblique_views_approach_from_above_on_the_camera_side() {
    use mvgrasp_core::{OBLIQUE_TILT_DEG, ViewAxis};
    let scene = grid_scene(0.1, 5, 5, 0.12);
    let camera = Camera::orbit(Vector3::new(0.0, 0.0, 0.1), 0.8, 50.0, -90.0);
    let config = PlannerConfig {
        views: ViewAxis::EVERY.to_vec(),
        ..PlannerConfig::default()
    };
    let cone = mvgrasp_core::ApproachCone::new(-Vector3::z(), 50f64.to_radians()).unwrap();
    let options = PlanOptions {
        view_policy: ViewPolicy::All,
        max_grasps: 200,
        min_quality: 0.1,
        approach_cone: Some(cone),
        ..PlanOptions::default()
    };
    let (plan, _) = crate::plan_rendered_with(config, &scene, &camera, &options);
    assert_eq!(
        plan.outside_approach_cone, 0,
        "front and side views are not inferred"
    );
    let eye = camera.world_from_camera.translation.vector;
    let mut oblique = 0;
    for g in &plan.grasps {
        let a = approach_of(g);
        match g.view {
            ViewAxis::TopFront | ViewAxis::TopSide => {
                oblique += 1;
                let off_vertical = (-a.z).acos().to_degrees();
                assert!((off_vertical - OBLIQUE_TILT_DEG).abs() < 1e-6, "{off_vertical}");
                // Approaching from the camera's side: the approach's
                // horizontal part points away from the camera.
                let to_camera = eye - g.world_from_grasp.translation.vector;
                assert!(a.x * to_camera.x + a.y * to_camera.y < 0.0, "{:?}", g.view);
            }
            ViewAxis::Top => assert!(a.z < -0.999),
            ViewAxis::Front | ViewAxis::Side => panic!("a horizontal grasp passed a 50-degree cone"),
        }
    }
    assert!(oblique > 0, "the oblique views gave grasps");
    for object in &plan.objects {
        assert_eq!(object.views.len(), 5);
        assert!(
            plan.grasps.iter().any(|g| g.object_id == object.id),
            "object {}",
            object.id
        );
    }
}
