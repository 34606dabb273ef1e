//! The hand check on rendered scenes: refusals between close neighbours,
//! its repairs (opening re-fits, turns away from a neighbour or off the
//! object, going deeper) and grasps reaching past the image border.

use mvgrasp_core::decode::HandConfig;
use mvgrasp_core::{
    GraspNet, MomentsNet, Plan, PlanOptions, Planner, PlannerConfig, Repairs, ViewPolicy, approach_of,
};
use nalgebra::{Point3, Vector3};

use crate::scene::{self, Camera, Scene, Shape, grid_scene};
use crate::table_workspace;

/// Objects 7 cm apart leave little room for the fingers: the hand check
/// refuses some of the baseline's grasps, every grasp it keeps is one the
/// unchecked planner also found, and with the check off nothing is refused.
#[test]
fn the_hand_check_refuses_grasps_between_close_neighbours() {
    let scene = grid_scene(0.0, 6, 3, 0.07);
    let camera = Camera::orbit(Vector3::zeros(), 0.8, 55.0, -90.0);
    let [checked, unchecked] = plans_with_hands(
        &scene,
        &camera,
        &mut MomentsNet::default(),
        [hand_without_repairs(), hand_off()],
    );
    assert_eq!(unchecked.refused_for_collision, 0);
    assert!(
        checked.refused_for_collision > 0,
        "no grasp refused among neighbours 7 cm apart"
    );
    let r = checked.refusals;
    assert_eq!(
        r.table + r.own_object + r.neighbour,
        checked.refused_for_collision
    );
    assert!(r.neighbour > 0, "{r:?}");
    assert!(!checked.grasps.is_empty());
    for g in &checked.grasps {
        assert!(
            unchecked
                .grasps
                .iter()
                .any(|u| u.world_from_grasp == g.world_from_grasp && u.width_m == g.width_m),
            "a checked grasp the unchecked planner did not find"
        );
    }
}

/// A network that opens too little puts the pads on the object: the check
/// refuses such grasps, and re-fitting the opening to the object's points
/// turns them into wider grasps at the same pixels that clear it.
#[test]
fn openings_too_narrow_for_the_object_are_re_fitted() {
    let scene = Scene {
        table_z: 0.0,
        table_half: [0.6, 0.4],
        shapes: vec![Shape::standing_box(0.0, 0.0, 0.0, 0.4, [0.06, 0.04, 0.10])],
    };
    let camera = Camera::orbit(Vector3::zeros(), 0.8, 50.0, -90.0);
    // The baseline's openings, 3 cm short of the object on each side: the
    // planner's 2 cm opening margin and the pads' 2 cm clearance leave the
    // pads 1 cm into it on each side.
    let mut net = MomentsNet::default();
    net.margin_m = -0.03;
    let [refused, fitted, unchecked] = plans_with_hands(
        &scene,
        &camera,
        &mut net,
        [
            hand_without_repairs(),
            // Re-fitted only, not pushed deeper, to compare poses.
            HandConfig {
                deepen_m: 0.0,
                ..HandConfig::default()
            },
            hand_off(),
        ],
    );
    assert!(
        refused.refused_for_collision > 0,
        "narrow openings passed the check"
    );
    // One box alone on the table: what the pads hit is the box itself.
    assert_eq!(refused.refusals.own_object, refused.refused_for_collision);
    assert!(fitted.refused_for_collision < refused.refused_for_collision);
    // Every decoded grasp was asked about: it is kept (maybe re-fitted) or refused.
    assert_eq!(
        fitted.grasps.len() + fitted.refused_for_collision,
        unchecked.grasps.len()
    );
    // Without the hand check nothing is repaired.
    assert!(unchecked.grasps.iter().all(|g| g.repairs == Repairs::default()));
    let mut refits = 0;
    for g in &fitted.grasps {
        if refused.grasps.contains(g) {
            assert!(!g.repairs.refit, "{g:?}");
            continue;
        }
        refits += 1;
        // Each grasp says it was re-fitted, and nothing else.
        assert!(
            g.repairs.refit && !g.repairs.turned_away && !g.repairs.deepened,
            "{g:?}"
        );
        let original = unchecked
            .grasps
            .iter()
            .find(|u| u.object_id == g.object_id && u.view == g.view && u.pixel == g.pixel)
            .expect("a re-fit of a decoded grasp");
        assert_eq!(g.quality, original.quality);
        assert!(
            g.width_m > original.width_m + 0.01 && g.width_m <= PlanOptions::default().gripper.max_width_m,
            "re-fitted from {} m to {} m",
            original.width_m,
            g.width_m
        );
        // Moved along the closing direction only, within the original opening.
        let moved = g.world_from_grasp.translation.vector - original.world_from_grasp.translation.vector;
        let closing = original.world_from_grasp.rotation * Vector3::x();
        assert!((moved - closing * moved.dot(&closing)).norm() < 1e-9);
        assert!(moved.norm() <= original.width_m / 2.0 + 1e-9);
        assert_eq!(g.world_from_grasp.rotation, original.world_from_grasp.rotation);
    }
    assert_eq!(
        refits,
        refused.refused_for_collision - fitted.refused_for_collision
    );
}

/// An object cut by the image border looks narrower than it is: a grasp
/// whose pads reach past the border may land one of them on the part never
/// seen. Such grasps are ranked after every grasp that stays in view (not
/// dropped: the object may have no other); an object well inside the image
/// is planned as without the check.
#[test]
fn grasps_reaching_past_the_image_border_are_ranked_last() {
    // Straight down from 0.7 m, 160 x 120 px at 150 px: columns run along
    // world x, and the table is seen out to x = 80 / 150 * 0.7 = 0.373 m.
    let camera = Camera::looking_at(Vector3::new(0.0, 0.0, 0.7), Vector3::zeros(), 160, 120, 150.0);
    // A palm no wider than the opening: this low box's side grasps closing
    // upright then clear the table, and it has grasps on both sides of the
    // border.
    let hand = HandConfig {
        palm_min_span_m: 0.0,
        ..HandConfig::default()
    };
    let unbounded = HandConfig {
        out_of_view_last: false,
        ..hand.clone()
    };
    // Where the pads' outer corners fall in the image, computed here from
    // the hand's dimensions (DESIGN.md's grasp frame: x closing, z approach).
    let gripper = PlanOptions::default().gripper;
    let reaches_past_border = |g: &mvgrasp_core::Grasp| {
        let half =
            (g.width_m + hand.opening_clearance_m).min(gripper.max_width_m) / 2.0 + hand.pad_thickness_m;
        [-half, half].into_iter().any(|x| {
            [-1.0, 1.0].into_iter().any(|side| {
                [0.0, -gripper.finger_depth_m].into_iter().any(|z| {
                    let world = g.world_from_grasp * Point3::new(x, side * gripper.finger_width_m / 2.0, z);
                    let c = camera.world_from_camera.inverse_transform_point(&world);
                    let u = camera.intrinsics.fx * c.x / c.z + camera.intrinsics.cx;
                    let v = camera.intrinsics.fy * c.y / c.z + camera.intrinsics.cy;
                    !(-0.5..=159.5).contains(&u) || !(-0.5..=119.5).contains(&v)
                })
            })
        })
    };
    let box_at = |x: f64| Scene {
        table_z: 0.0,
        table_half: [0.6, 0.4],
        shapes: vec![Shape::standing_box(0.0, x, 0.0, 0.0, [0.06, 0.09, 0.08])],
    };
    let sorted = |plan: &Plan| {
        let mut keys: Vec<_> = plan
            .grasps
            .iter()
            .map(|g| (g.view, g.pixel, g.width_m.to_bits()))
            .collect();
        keys.sort();
        keys
    };

    // 6 cm along x from 0.30 to 0.36 m: its top (0.62 m from the camera) is
    // seen only out to 0.331 m, half of it.
    let [bounded, free] = plans_with_hands(
        &box_at(0.33),
        &camera,
        &mut MomentsNet::default(),
        [hand.clone(), unbounded.clone()],
    );
    let past: Vec<bool> = free.grasps.iter().map(reaches_past_border).collect();
    assert!(past.contains(&true) && past.contains(&false), "{past:?}");
    assert!(
        past.windows(2).any(|w| w[0] && !w[1]),
        "unchecked, a grasp past the border already ranks last"
    );
    // Checked: the same grasps, those past the border all at the end.
    assert_eq!(sorted(&bounded), sorted(&free));
    let past: Vec<bool> = bounded.grasps.iter().map(reaches_past_border).collect();
    let first_past = past.iter().position(|&p| p).expect("a grasp past the border");
    assert!(past[first_past..].iter().all(|&p| p), "{past:?}");
    assert_eq!(bounded.ranked_last_out_of_view, past.len() - first_past);
    assert_eq!(free.ranked_last_out_of_view, 0);
    // Each grasp says whether it was ranked last for the border.
    let flagged: Vec<bool> = bounded.grasps.iter().map(|g| g.repairs.out_of_view).collect();
    assert_eq!(flagged, past);
    assert!(free.grasps.iter().all(|g| !g.repairs.out_of_view));
    assert_eq!(bounded.refused_for_collision, free.refused_for_collision);

    // In the middle of the image the check changes nothing.
    let [bounded, free] = plans_with_hands(
        &box_at(0.0),
        &camera,
        &mut MomentsNet::default(),
        [hand, unbounded],
    );
    assert!(!free.grasps.is_empty());
    assert_eq!(bounded.grasps, free.grasps);
    assert_eq!(bounded.ranked_last_out_of_view, 0);
}

/// A grasp whose hand would hit a neighbour as planned is turned about its
/// approach until it no longer does, and ranked after every grasp that
/// passed as planned; without turns it is refused.
#[test]
fn grasps_into_a_neighbour_are_turned_away_and_ranked_after() {
    // A 6 x 4 cm box, 10 cm tall; a 9 cm tall neighbour 1.5 cm off its
    // 4 cm side: closing across the 4 cm, the pads come down beside the
    // box onto the neighbour's top edge.
    let scene = Scene {
        table_z: 0.0,
        table_half: [0.6, 0.4],
        shapes: vec![
            Shape::standing_box(0.0, 0.0, 0.0, 0.0, [0.06, 0.04, 0.10]),
            Shape::standing_box(0.0, 0.0, 0.055, 0.0, [0.06, 0.04, 0.09]),
        ],
    };
    let camera = Camera::orbit(Vector3::zeros(), 0.8, 50.0, -90.0);
    let hand = HandConfig::default();
    let no_turns = HandConfig {
        neighbour_turns_deg: Vec::new(),
        ..hand.clone()
    };
    let [refused, turned, unchecked] = plans_with_hands(
        &scene,
        &camera,
        &mut MomentsNet::default(),
        [no_turns, hand.clone(), hand_off()],
    );
    assert_eq!(refused.objects.len(), 2, "the two boxes apart");
    assert!(refused.refusals.neighbour > 0, "{:?}", refused.refusals);
    assert_eq!(refused.ranked_after_turned_away, 0);
    let n = turned.ranked_after_turned_away;
    assert!(n > 0, "no grasp turned away: {:?}", turned.refusals);
    // Every turned grasp is one the check refused without turns.
    assert_eq!(turned.refused_for_collision + n, refused.refused_for_collision);
    assert_eq!(turned.refusals.neighbour + n, refused.refusals.neighbour);
    // The grasps as planned are the same; the turned come after them.
    let first_turned = turned.grasps.len() - n - turned.ranked_last_out_of_view;
    assert_eq!(turned.grasps[..first_turned], refused.grasps[..first_turned]);
    // Each grasp says whether it was turned away.
    let flagged: Vec<bool> = turned.grasps[..first_turned + n]
        .iter()
        .map(|g| g.repairs.turned_away)
        .collect();
    assert!(
        flagged[..first_turned].iter().all(|&t| !t) && flagged[first_turned..].iter().all(|&t| t),
        "{flagged:?}"
    );
    assert!(refused.grasps.iter().all(|g| !g.repairs.turned_away));
    for g in &turned.grasps[first_turned..first_turned + n] {
        let original = unchecked
            .grasps
            .iter()
            .find(|u| u.object_id == g.object_id && u.view == g.view && u.pixel == g.pixel)
            .expect("a turn of a decoded grasp");
        assert!(!refused.grasps.contains(original));
        assert_eq!(g.quality, original.quality);
        // The same approach; the closing direction turned by one of the
        // turns (the squaring may add up to its own limit).
        assert!((approach_of(g) - approach_of(original)).norm() < 1e-9);
        let closing = |p: &mvgrasp_core::Grasp| p.world_from_grasp.rotation * Vector3::x();
        let turn = closing(g)
            .dot(&closing(original))
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        assert!(
            hand.neighbour_turns_deg
                .iter()
                .any(|t| (turn - t.abs()).abs() <= hand.square_turn_deg + 1e-6),
            "turned {turn} degrees"
        );
        assert!(turn >= 20.0 - hand.square_turn_deg, "turned {turn} degrees");
    }
}

/// The hand check without its repairs: no opening re-fit, no turn away
/// from a neighbour, no push deeper.
fn hand_without_repairs() -> HandConfig {
    HandConfig {
        fit_opening: false,
        neighbour_turns_deg: Vec::new(),
        deepen_m: 0.0,
        deepen_to_middle_m: 0.0,
        ..HandConfig::default()
    }
}

/// No hand check at all.
fn hand_off() -> HandConfig {
    HandConfig {
        enabled: false,
        ..HandConfig::default()
    }
}

/// The analytic baseline with every grasp angle turned by 90 degrees: it
/// closes along an elongated object instead of across it.
struct Crosswise(MomentsNet);

impl GraspNet for Crosswise {
    fn contract(&self) -> &mvgrasp_core::ModelContract {
        self.0.contract()
    }

    fn infer(&mut self, batch: &mvgrasp_core::ViewBatch) -> mvgrasp_core::Result<mvgrasp_core::GraspMaps> {
        let mut maps = self.0.infer(batch)?;
        let outputs = self.0.contract().outputs;
        let pixels = maps.size_px * maps.size_px;
        for view in 0..maps.len {
            for (c, channel) in outputs.iter().enumerate() {
                if matches!(
                    channel,
                    mvgrasp_core::Channel::Cos2Phi | mvgrasp_core::Channel::Sin2Phi
                ) {
                    let start = (view * 4 + c) * pixels;
                    maps.data[start..start + pixels].iter_mut().for_each(|v| *v = -*v);
                }
            }
        }
        Ok(maps)
    }
}

/// A grasp whose pads would land on its own object, with no opening within
/// the stroke that clears it, is turned about its approach until the hand
/// passes, and ranked after the grasps that passed as planned: an 18 cm
/// long box (the 2F-140 opens 14 cm), grasped lengthwise, is turned until
/// the pads clear it.
#[test]
fn grasps_onto_their_own_object_are_turned_until_they_fit() {
    let scene = Scene {
        table_z: 0.0,
        table_half: [0.6, 0.4],
        shapes: vec![Shape::standing_box(0.0, 0.0, 0.0, 0.0, [0.18, 0.05, 0.06])],
    };
    let camera = Camera::orbit(Vector3::zeros(), 0.8, 60.0, -90.0);
    let rendered = scene::render(&scene, &camera);
    let bytes = rendered.depth_bytes();
    let input = camera.scene_input(&bytes, table_workspace(&scene));
    let options = PlanOptions {
        view_policy: ViewPolicy::TopDown,
        max_grasps: 100,
        min_quality: 0.0,
        view_cascade: false,
        ..PlanOptions::default()
    };
    let hand = HandConfig::default();
    let no_turns = HandConfig {
        neighbour_turns_deg: Vec::new(),
        ..hand.clone()
    };
    let [refused, turned] = [no_turns, hand].map(|hand| {
        let mut net = Crosswise(MomentsNet::default());
        let config = PlannerConfig {
            hand,
            max_grasps_per_object: 100,
            ..PlannerConfig::default()
        };
        let planner = Planner::new(config, net.contract().clone()).expect("planner");
        planner.plan(&input, &options, &mut net).expect("plan")
    });
    assert_eq!(refused.objects.len(), 1);
    assert!(refused.refusals.own_object > 0, "{:?}", refused.refusals);
    assert!(
        refused.grasps.is_empty(),
        "lengthwise grasps cannot clear an 18 cm box"
    );
    assert!(turned.ranked_after_turned_away > 0, "{:?}", turned.refusals);
    assert_eq!(turned.grasps.len(), turned.ranked_after_turned_away);
    for g in &turned.grasps {
        assert!(g.repairs.turned_away);
        let closing = g.world_from_grasp.rotation * Vector3::x();
        // At least 40 degrees off the length (45 degrees already clears: 7 cm across).
        assert!(
            closing.x.abs() < 40f64.to_radians().cos(),
            "turned off the length: {closing:?}"
        );
        assert!(g.width_m < 0.14);
    }
}

/// `scene` as `camera` sees it, planned once per hand setting (in order)
/// with every view, no quality floor and no per-object limit, so that the
/// plans differ only by what the hand check did.
fn plans_with_hands<const N: usize>(
    scene: &Scene,
    camera: &Camera,
    net: &mut MomentsNet,
    hands: [HandConfig; N],
) -> [Plan; N] {
    let rendered = scene::render(scene, camera);
    let bytes = rendered.depth_bytes();
    let input = camera.scene_input(&bytes, table_workspace(scene));
    let options = PlanOptions {
        view_policy: ViewPolicy::All,
        max_grasps: 1000,
        min_quality: 0.0,
        ..PlanOptions::default()
    };
    hands.map(|hand| {
        let config = PlannerConfig {
            hand,
            max_grasps_per_object: 1000,
            ..PlannerConfig::default()
        };
        let planner = Planner::new(config, net.contract().clone()).expect("planner");
        planner.plan(&input, &options, net).expect("plan")
    })
}

/// A 6 x 4 x 12 cm box turned 0.4 rad, seen from 50 degrees.
fn tall_box() -> (Scene, Camera) {
    let scene = Scene {
        table_z: 0.0,
        table_half: [0.6, 0.4],
        shapes: vec![Shape::standing_box(0.0, 0.0, 0.0, 0.4, [0.06, 0.04, 0.12])],
    };
    (scene, Camera::orbit(Vector3::zeros(), 0.8, 50.0, -90.0))
}

/// A grasp that passes the check goes 5 mm (or 2.5 mm) further along its
/// approach when the hand still passes there, and stays as it was
/// otherwise; nothing else about it changes (the push towards the middle
/// off, as measured apart below).
#[test]
fn grasps_go_deeper_where_the_hand_still_passes() {
    let (scene, camera) = tall_box();
    let hand = HandConfig {
        deepen_to_middle_m: 0.0,
        ..HandConfig::default()
    };
    let [deeper, as_planned] = plans_with_hands(
        &scene,
        &camera,
        &mut MomentsNet::default(),
        [
            hand.clone(),
            HandConfig {
                deepen_m: 0.0,
                ..hand.clone()
            },
        ],
    );
    assert_eq!(deeper.grasps.len(), as_planned.grasps.len());
    let mut moved = 0;
    for (d, a) in deeper.grasps.iter().zip(&as_planned.grasps) {
        assert_eq!(
            (d.object_id, d.view, d.pixel, d.quality, d.width_m),
            (a.object_id, a.view, a.pixel, a.quality, a.width_m)
        );
        assert_eq!(d.world_from_grasp.rotation, a.world_from_grasp.rotation);
        let approach = a.world_from_grasp.rotation * Vector3::z();
        let step = d.world_from_grasp.translation.vector - a.world_from_grasp.translation.vector;
        let along = step.dot(&approach);
        assert!((step - approach * along).norm() < 1e-9, "moved off the approach");
        assert!(
            [0.0, hand.deepen_m / 2.0, hand.deepen_m]
                .iter()
                .any(|&d| (along - d).abs() < 1e-9),
            "moved {along} m"
        );
        moved += usize::from(along > 0.0);
        // Each grasp says whether it went deeper; squaring is the same.
        assert_eq!(d.repairs.deepened, along > 0.0);
        assert!(!a.repairs.deepened);
        assert_eq!(d.repairs.squared, a.repairs.squared);
    }
    assert!(moved > 0, "no grasp went deeper on a 12 cm box");
    // Every grasp was kept (no caps here), so the squared ones it reports
    // are the plan's count of squaring turns.
    for plan in [&deeper, &as_planned] {
        let squared = plan.grasps.iter().filter(|g| g.repairs.squared).count();
        assert_eq!(squared, plan.turned_square);
    }
    assert!(
        deeper.turned_square > 0,
        "no grasp squared to a box turned 0.4 rad"
    );
}

/// By default (`deepen_to_middle_m`), a top grasp on a 12 cm box goes
/// towards the middle of the box's height, further than the 5 mm step alone
/// (`deepen_to_middle_m = 0`) and never further than allowed; side grasps
/// and everything else about each grasp stay as they were.
#[test]
fn grasps_on_a_tall_box_go_towards_its_middle() {
    let (scene, camera) = tall_box();
    let middle = HandConfig::default();
    assert!(middle.deepen_to_middle_m > middle.deepen_m);
    let hand = HandConfig {
        deepen_to_middle_m: 0.0,
        ..middle.clone()
    };
    let [towards, step_only] = plans_with_hands(
        &scene,
        &camera,
        &mut MomentsNet::default(),
        [middle.clone(), hand.clone()],
    );
    assert_eq!(towards.grasps.len(), step_only.grasps.len());
    let mut further = 0;
    for (t, s) in towards.grasps.iter().zip(&step_only.grasps) {
        assert_eq!(
            (t.object_id, t.view, t.pixel, t.quality, t.width_m),
            (s.object_id, s.view, s.pixel, s.quality, s.width_m)
        );
        let approach = s.world_from_grasp.rotation * Vector3::z();
        let along =
            (t.world_from_grasp.translation.vector - s.world_from_grasp.translation.vector).dot(&approach);
        assert!(along <= middle.deepen_to_middle_m + 1e-9, "moved {along} m");
        // Fingertips never pushed below the box's middle (6 cm) from above.
        if approach.z < -0.5 && along > 1e-9 {
            assert!(
                t.world_from_grasp.translation.z >= 0.06 - 1e-3,
                "{}",
                t.world_from_grasp.translation.z
            );
            further += 1;
        }
        if approach.z > -0.5 {
            assert!(along.abs() < 1e-9, "a side grasp moved {along} m");
        }
    }
    assert!(further > 0, "no top grasp went towards the middle of a 12 cm box");
}
