//! Training targets of a view (`sim::dataset`): which pixels, angles and widths are positive.

use mvgrasp_core::{Channel, ViewAxis};
use mvgrasp_sim::grasp::GripperModel;
use mvgrasp_sim::targets::{Opening, TargetConfig, label_frame};

use super::*;

fn labelled(size: [f32; 3]) -> Vec<mvgrasp_sim::targets::LabelledView> {
    labelled_with(size, &TargetConfig::default())
}

fn labelled_with(size: [f32; 3], config: &TargetConfig) -> Vec<mvgrasp_sim::targets::LabelledView> {
    let model = ObjectModel::from_parts(
        Family::Box,
        vec![(
            Pose::from_translation(Vector::new(0.0, 0.0, size[2] / 2.0)),
            SharedShape::cuboid(size[0] / 2.0, size[1] / 2.0, size[2] / 2.0),
        )],
    );
    let scene = one_object(0.2, model, 0.0, 0.0);
    let target = Vector3::new(0.0, 0.0, 0.2);
    let camera = Camera::looking_at(target + Vector3::new(0.5, -0.4, 0.5), target, 640, 480, 600.0);
    let mut rng = SplitMix64::new(1);
    let frame = render(&scene, &camera, Some((&NoiseModel::default(), &mut rng)));
    let net = MomentsNet::default();
    let planner = Planner::new(PlannerConfig::default(), net.contract().clone()).unwrap();
    label_frame(
        &scene,
        &frame,
        &planner,
        &GripperModel::robotiq_2f_140(),
        config,
        &mut rng,
    )
    .unwrap()
}

#[test]
fn the_pads_opening_reaches_past_the_silhouette_over_the_pads_strip() {
    // A disc of radius 10 px centred at (20.5, 20.5) in a 41 px view.
    let l = 41;
    let image: Vec<f32> = (0..l * l)
        .map(|i| {
            let (x, y) = ((i % l) as f64 - 20.0, (i / l) as f64 - 20.0);
            if x * x + y * y <= 100.0 { 0.5 } else { 0.0 }
        })
        .collect();
    let across = (1.0, 0.0);
    let chord = |x, y| Opening::Chord.width_px(&image, l, x, y, across, 8.0);
    let pads = |x, y| Opening::Pads.width_px(&image, l, x, y, across, 8.0);
    // Through the centre (pixels 10..=30 of row 20; the half-pixel
    // steps reach 10 px right and 10.5 px left): the middle row is the
    // widest in the strip, so the pads need its wider side twice.
    assert_eq!(chord(20.5, 20.5), 21.5);
    assert_eq!(pads(20.5, 20.5), 22.0);
    // 6 px right of the centre the chord is the same, but the pads,
    // symmetric about the pixel, must clear the 16.5 px to its left.
    assert_eq!(chord(26.5, 20.5), 21.5);
    assert_eq!(pads(26.5, 20.5), 34.0);
    // 8 px below the centre the chord through the pixel (row 28, pixels
    // 14..=26) is short; the strip, 4 px either side, holds row 24
    // (pixels 11..=29).
    assert_eq!(chord(20.5, 28.5), 13.5);
    assert_eq!(pads(20.5, 28.5), 20.0);
    assert_eq!("pads".parse::<Opening>().unwrap(), Opening::Pads);
    assert!(
        "wide"
            .parse::<Opening>()
            .unwrap_err()
            .to_string()
            .contains("chord or pads")
    );
}

#[test]
fn candidates_opened_over_the_pads_start_outside_a_box_and_lose_no_positive() {
    let size = [0.06, 0.04, 0.10];
    let chord = labelled(size);
    let pads = labelled_with(
        size,
        &TargetConfig {
            opening: Opening::Pads,
            ..TargetConfig::default()
        },
    );
    let pad_hits =
        |v: &mvgrasp_sim::targets::LabelledView| v.refused.get("object: pad").copied().unwrap_or(0);
    for (c, p) in chord.iter().zip(&pads) {
        assert_eq!(
            (c.axis, c.candidates),
            (p.axis, p.candidates),
            "the same views and candidates"
        );
        println!(
            "{:?}: positives {} -> {}, pad on the object {} -> {}",
            c.axis,
            c.positives,
            p.positives,
            pad_hits(c),
            pad_hits(p)
        );
    }
    // Off the chord's middle the pads now start outside the box: the
    // refusals for a pad in the object all but vanish (top 125 -> 0,
    // front 219 -> 9, side 258 -> 0 when written), and no view loses a
    // positive.
    for (c, p) in chord.iter().zip(&pads) {
        assert!(
            pad_hits(p) * 10 <= pad_hits(c),
            "{:?}: {} vs {}",
            c.axis,
            pad_hits(p),
            pad_hits(c)
        );
        assert!(
            p.positives >= c.positives,
            "{:?}: {} vs {}",
            c.axis,
            p.positives,
            c.positives
        );
    }
}

#[test]
fn a_graspable_box_gets_consistent_targets_and_a_wide_one_none_from_above() {
    let contract = MomentsNet::default().contract().clone();
    let l = contract.input_size_px;
    let (q, c, s, w) = (
        contract.channel_index(Channel::Quality),
        contract.channel_index(Channel::Cos2Phi),
        contract.channel_index(Channel::Sin2Phi),
        contract.channel_index(Channel::Width),
    );
    let views = labelled([0.06, 0.04, 0.10]);
    assert_eq!(views.len(), 3, "top, front and side views of the one object");
    for v in &views {
        println!(
            "{:?}: {} of {} candidates positive",
            v.axis, v.positives, v.candidates
        );
    }
    let top = views.iter().find(|v| v.axis == ViewAxis::Top).unwrap();
    assert!(
        top.positives > 20,
        "{} of {} candidates",
        top.positives,
        top.candidates
    );
    for view in &views {
        assert_eq!(view.object, 0);
        assert_eq!(view.grasps.len(), view.positives);
        // Every candidate is a positive or refused for a named reason.
        let refused: usize = view.refused.values().sum();
        assert_eq!(view.positives + refused, view.candidates, "{:?}", view.refused);
        for g in &view.grasps {
            // Each positive is painted at its own pixel, at least as high.
            let i = g.v * l + g.u;
            assert!(view.maps[q * l * l + i] >= g.quality && g.quality > 0.0);
            assert!(g.phi.abs() <= std::f32::consts::FRAC_PI_2 + 1e-6, "{}", g.phi);
            assert!(g.width_m > 0.0 && g.width_m <= 0.14, "{}", g.width_m);
        }
        for i in 0..l * l {
            let quality = view.maps[q * l * l + i];
            let (cos2, sin2, width) = (
                view.maps[c * l * l + i],
                view.maps[s * l * l + i],
                view.maps[w * l * l + i],
            );
            assert!((0.0..=1.0).contains(&quality));
            if quality > 0.0 {
                assert!((cos2 * cos2 + sin2 * sin2 - 1.0).abs() < 1e-4);
                let width_m = width * contract.width_scale_m;
                assert!(width_m > 0.0 && width_m <= 0.14, "{width_m}");
                assert!(
                    view.image[i] > 0.0 || quality < 1.0,
                    "painted only on or next to the object"
                );
            } else {
                assert_eq!((cos2, sin2, width), (0.0, 0.0, 0.0));
            }
        }
    }
    // 20 x 16 cm seen from above: both ways across exceed the 14 cm stroke.
    let wide = labelled([0.20, 0.16, 0.10]);
    let top = wide.iter().find(|v| v.axis == ViewAxis::Top).unwrap();
    assert_eq!(top.positives, 0, "of {} candidates", top.candidates);
    // And the labeller says so: most candidates are wider than the stroke.
    let most = top.refused.iter().max_by_key(|(_, n)| **n).map(|(why, _)| *why);
    assert_eq!(most, Some("over stroke"), "{:?}", top.refused);
}
