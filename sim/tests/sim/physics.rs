//! The rapier3d trials (`sim::physics`): close, lift, shake, carry, let go.

use mvgrasp_sim::grasp::{GraspLabel, GripperModel, label_grasp};
use mvgrasp_sim::physics::{Basket, TrialConfig, TrialOutcome, rest_to_rest, run_trial, trial};
use nalgebra::Vector3 as V3;

use super::grasp_labels::{box_scene, top_down_grasp};
use super::*;

#[test]
fn the_carry_speeds_up_and_slows_down_within_its_acceleration() {
    let (speed, accel, dt) = (0.5f32, 1.0f32, 1.0 / 240.0);
    for length in [0.0f32, 0.003, 0.1, 0.8] {
        let path: Vec<f32> = std::iter::once(0.0)
            .chain(rest_to_rest(length, speed, accel, dt))
            .collect();
        assert!(
            (path.last().unwrap() - length).abs() < 1e-6,
            "{length}: ends at {:?}",
            path.last()
        );
        let v: Vec<f32> = std::iter::once(0.0)
            .chain(path.windows(2).map(|w| (w[1] - w[0]) / dt))
            .chain(std::iter::once(0.0))
            .collect();
        assert!(v.iter().all(|&v| v <= speed + 1e-4), "{length}: over speed");
        // Speed changes by at most accel * dt per step, both ways (the
        // last step rounds onto the end: 1e-5 m of slack).
        let worst = v.windows(2).map(|w| (w[1] - w[0]).abs()).fold(0.0f32, f32::max);
        assert!(
            worst <= accel * dt * 1.01 + 1e-5 / dt,
            "{length}: {worst} m/s in one step"
        );
    }
    // 0.8 m: 0.5 s up to speed (0.125 m), 0.55 m cruising, 0.5 s down: 2.1 s.
    let steps = rest_to_rest(0.8, speed, accel, dt).count() as f32;
    assert!((steps * dt - 2.1).abs() < 0.02, "{} s", steps * dt);
}

#[test]
fn a_narrow_side_grasp_lifts_and_a_grasp_over_a_ball_does_not() {
    let g = GripperModel::robotiq_2f_140();
    let config = TrialConfig::default();
    // Positive analytically and in physics: across the 4 cm side, 4 cm deep.
    let scene = box_scene([0.06, 0.04, 0.10]);
    let grasp = top_down_grasp(0.0, 0.0, 0.06, V3::y());
    assert!(label_grasp(&scene, 0, &grasp, 0.04, &g).is_positive());
    let outcome = trial(&scene, 0, &grasp, 0.04, &g, &config);
    assert!(
        matches!(outcome, TrialOutcome::Held { lifted_m } if lifted_m > 0.14),
        "{outcome:?}"
    );
    // Negative both ways: pads meeting a 4 cm ball 6 mm below its top,
    // where its surface faces up at about 55 degrees.
    let ball = ObjectModel::from_parts(
        Family::Ellipsoid,
        vec![(
            Pose::from_translation(Vector::new(0.0, 0.0, 0.04)),
            SharedShape::ball(0.04),
        )],
    );
    let scene = one_object(0.0, ball, 0.0, 0.0);
    let grasp = top_down_grasp(0.0, 0.0, 0.074, V3::y());
    assert!(matches!(
        label_grasp(&scene, 0, &grasp, 0.04, &g),
        GraspLabel::NotAntipodal { .. }
    ));
    let outcome = trial(&scene, 0, &grasp, 0.04, &g, &config);
    assert!(!outcome.is_held(), "{outcome:?}");
    // Nothing between the pads: no grip.
    let scene = box_scene([0.06, 0.04, 0.10]);
    let outcome = trial(
        &scene,
        0,
        &top_down_grasp(0.0, 0.2, 0.06, V3::y()),
        0.04,
        &g,
        &config,
    );
    assert_eq!(outcome, TrialOutcome::NoGrip);
}

#[test]
fn a_held_box_is_carried_over_its_neighbour_into_the_basket() {
    let g = GripperModel::robotiq_2f_140();
    let basket = Basket::default();
    let config = TrialConfig {
        carry: Some(basket),
        ..TrialConfig::default()
    };
    // The box, and a 25 cm tall box between it and the basket (at y = -0.75).
    let mut scene = box_scene([0.06, 0.04, 0.10]);
    let mut tall = box_scene([0.05, 0.05, 0.25]).objects.remove(0);
    tall.world_from_object.translation.y -= 0.3;
    tall.world_aabb = tall.model.aabb_at(&tall.world_from_object);
    scene.objects.push(tall);
    let grasp = top_down_grasp(0.0, 0.0, 0.06, V3::y());
    let result = run_trial(&scene, 0, &grasp, 0.04, &g, &config);
    assert!(result.outcome.is_held(), "{:?}", result.outcome);
    let [bx, by] = basket.centre_xy;
    let box_at = result.poses[0].translation;
    assert!(
        (box_at.x - bx).abs() < basket.inner_half_m && (box_at.y - by).abs() < basket.inner_half_m,
        "the box rests at {box_at:?}, the basket is at ({bx}, {by})"
    );
    assert!(box_at.z < scene.table_z + 0.1, "the box was let go: {box_at:?}");
    // Carried over the tall one, not through it: it did not move.
    let tall_moved = (result.poses[1].translation - scene.objects[1].world_from_object.translation).length();
    assert!(tall_moved < 0.002, "the neighbour moved {tall_moved} m");
    // A grasp that never grips leaves the scene where it was.
    let missed = run_trial(
        &scene,
        0,
        &top_down_grasp(0.0, 0.2, 0.06, V3::y()),
        0.04,
        &g,
        &config,
    );
    assert_eq!(missed.outcome, TrialOutcome::NoGrip);
    let box_moved = (missed.poses[0].translation - scene.objects[0].world_from_object.translation).length();
    assert!(box_moved < 0.002, "the box moved {box_moved} m");
}
