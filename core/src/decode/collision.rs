//! Does the hand hit what the camera saw? A check of each grasp, in rank
//! order, before it is returned.
//!
//! The hand's boxes (`hand`) are checked where the hand ends and swept back
//! along the approach by `approach_m`, pre-shaped `preshape_margin_m` wider
//! (within the stroke), as a robot arrives. A grasp collides when at least
//! `min_points` of one detected object's points fall inside (one stray
//! reading is not an obstacle), or when a box corner reaches under the
//! table plane. The object's own points count in the pads and the palm:
//! pads that land on the object are a failed grasp as much as pads that
//! land on its neighbour. Another object's points count between the pads
//! too (the hand would close on it, or meet it with the palm on the way
//! down). Where the approach starts, the hand must also keep out of every
//! other object's box (`HandConfig::pregrasp_boxes`), as the robot-bridge
//! checks its pre-grasp. A refused grasp may get another chance (`repair`).
//!
//! What the camera never saw is not known to be free: an object cut by the
//! image border looks narrower than it is, and a pad reaching past the
//! border may land on the part outside. [`hand_out_of_view`] finds such
//! grasps (depth frames, whose border is known); the pipeline ranks them
//! after every grasp that stays in view rather than dropping them, as the
//! object may have no other grasp (`HandConfig::out_of_view_last`).
//!
//! Cost: the points are each object's, in its own frame (kept from the
//! views). Each hand box's bounding box is found in that frame; an object
//! none of them reaches is skipped, a point outside all of them costs a few
//! compares, and only the rest are moved into the grasp frame (f32).

use nalgebra::{Isometry3, Point3, Vector3};

use super::hand::{GraspBox, HandConfig, finger_reach, gap_box, hand_boxes, widen};
use crate::gripper::Gripper;
use crate::segment::TablePlane;
use crate::sensor::FieldOfView;

/// The observed points of one detected object, in its own frame.
#[derive(Debug, Clone, Copy)]
pub struct Obstacle<'a> {
    /// Maps object-frame points to the world.
    pub world_from_object: &'a Isometry3<f64>,
    /// Lower corner of the points' box (object frame).
    pub extent_min_m: &'a Vector3<f64>,
    /// Upper corner of the points' box (object frame).
    pub extent_max_m: &'a Vector3<f64>,
    /// The points (object frame).
    pub points: &'a [[f32; 3]],
}

/// What a hand hits first: the table is checked before the objects, and
/// the objects in the order given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Collision {
    /// A hand box dips under the table.
    Table,
    /// The observed points of `obstacles[i]`.
    Object(usize),
}

/// Whether a pad, where the hand ends (opened to `width_m` plus the
/// opening clearance), reaches outside `view`. An object cut by the image
/// border looks narrower than it is: the pad on the cut side would land on
/// the part never seen. The pads' corners are checked; the field of view is
/// convex, so the pads and the gap between them are inside when every
/// corner is.
pub fn hand_out_of_view(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    view: &FieldOfView,
) -> bool {
    let open = widen(width_m, hand.opening_clearance_m, gripper);
    hand_boxes(open, 0.0, 0.0, gripper.finger_depth_m, gripper, hand)[..2]
        .iter()
        .flat_map(GraspBox::corners)
        .any(|c| !view.contains(&(world_from_grasp * Point3::from(c))))
}

/// Whether the hand, closing to `width_m` at `world_from_grasp` after its
/// approach, would hit the observed points of `obstacles` or the table,
/// or start its approach inside another object's box.
/// `own` is the grasp's own object among `obstacles`: only its points may
/// lie between the pads, where the hand ends or on the way in; another
/// object's points there would be closed on, or met by the palm on the way
/// down.
pub fn hand_collides(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    table: &TablePlane,
    obstacles: &[Obstacle<'_>],
    own: Option<usize>,
) -> bool {
    hand_collision(world_from_grasp, width_m, gripper, hand, table, obstacles, own).is_some()
}

/// [`hand_collides`], saying what the hand hits first.
pub fn hand_collision(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    table: &TablePlane,
    obstacles: &[Obstacle<'_>],
    own: Option<usize>,
) -> Option<Collision> {
    if !hand.enabled {
        return None;
    }
    let open = widen(width_m, hand.opening_clearance_m, gripper);
    let preshaped = widen(open, hand.preshape_margin_m, gripper);
    // Where the hand ends, and the approach behind it (pre-shaped wider).
    let reach = finger_reach(gripper, hand);
    let mut boxes = hand_boxes(open, 0.0, 0.0, reach, gripper, hand).to_vec();
    boxes.extend(hand_boxes(
        preshaped,
        -1e-3,
        hand.approach_m,
        reach,
        gripper,
        hand,
    ));

    // Corner heights above the table: the plane's normal in the grasp frame
    // makes each a dot product.
    let normal_in_grasp = world_from_grasp.rotation.inverse() * table.normal;
    let origin_height = table.height_of(&world_from_grasp.translation.vector);
    if boxes
        .iter()
        .flat_map(GraspBox::corners)
        .any(|c| origin_height + normal_in_grasp.dot(&c) < hand.table_margin_m)
    {
        return Some(Collision::Table);
    }
    // Between the pads, where the hand ends and on the way in: only the
    // grasp's own object may be there.
    let hand_only = boxes.len();
    boxes.push(gap_box(open, 0.0, 0.0, reach, gripper));
    boxes.push(gap_box(preshaped, -1e-3, hand.approach_m, reach, gripper));
    let boxes_f32: Vec<([f32; 3], [f32; 3])> = boxes
        .iter()
        .map(|b| (b.lo.map(|v| v as f32).into(), b.hi.map(|v| v as f32).into()))
        .collect();
    let by_points = obstacles.iter().enumerate().position(|(i, o)| {
        let n = if own == Some(i) { hand_only } else { boxes.len() };
        hits_object(world_from_grasp, &boxes[..n], &boxes_f32[..n], hand.min_points, o)
    });
    if by_points.is_some() || !hand.pregrasp_boxes {
        return by_points.map(Collision::Object);
    }
    // Where the approach starts, the hand against the other objects'
    // boxes, as the robot-bridge checks its pre-grasp.
    let margin = Vector3::repeat(hand.pregrasp_box_margin_m);
    let at_start = hand_boxes(preshaped, -hand.approach_m, 0.0, reach, gripper, hand).map(|b| GraspBox {
        lo: b.lo - margin,
        hi: b.hi + margin,
    });
    obstacles
        .iter()
        .enumerate()
        .position(|(i, o)| own != Some(i) && meets_box(world_from_grasp, &at_start, o))
        .map(Collision::Object)
}

/// Whether any of `boxes` (grasp frame) overlaps `object`'s box (its seen
/// extent, in its own frame): no separating axis among the two boxes'
/// three axes each and the nine cross products between them. A box whose
/// bounding sphere misses the object's is skipped first.
fn meets_box(world_from_grasp: &Isometry3<f64>, boxes: &[GraspBox], object: &Obstacle<'_>) -> bool {
    let object_from_grasp = object.world_from_object.inverse() * world_from_grasp;
    let rotation = object_from_grasp.rotation.to_rotation_matrix().into_inner();
    let grasp_axes = [0, 1, 2].map(|k| rotation.column(k).into_owned());
    let object_axes = [Vector3::x(), Vector3::y(), Vector3::z()];
    let half_object = (object.extent_max_m - object.extent_min_m) / 2.0;
    let centre_object = Point3::from((object.extent_max_m + object.extent_min_m) / 2.0);
    boxes.iter().any(|b| {
        let half_hand = (b.hi - b.lo) / 2.0;
        let apart = object_from_grasp * Point3::from((b.lo + b.hi) / 2.0) - centre_object;
        if apart.norm() > half_object.norm() + half_hand.norm() {
            return false;
        }
        // Each box's half length along `axis` (any length), against the
        // centres' distance along it.
        let separates = |axis: Vector3<f64>| {
            let spread = |axes: &[Vector3<f64>; 3], half: &Vector3<f64>| {
                (0..3).map(|k| half[k] * axes[k].dot(&axis).abs()).sum::<f64>()
            };
            axis.norm_squared() > 1e-18
                && apart.dot(&axis).abs()
                    > spread(&object_axes, &half_object) + spread(&grasp_axes, &half_hand)
        };
        let crossed = object_axes
            .iter()
            .flat_map(|a| grasp_axes.iter().map(move |g| a.cross(g)));
        !object_axes
            .iter()
            .chain(&grasp_axes)
            .copied()
            .chain(crossed)
            .any(separates)
    })
}

/// `f` of each of `object`'s points inside `b`, in the grasp frame (f32);
/// none when `b` does not reach the object's box.
pub(super) fn points_inside<T>(
    world_from_grasp: &Isometry3<f64>,
    b: &GraspBox,
    object: &Obstacle<'_>,
    f: impl FnMut([f32; 3]) -> T,
) -> Vec<T> {
    let Some(seen) = SeenFromGrasp::new(world_from_grasp, &[*b], object) else {
        return Vec::new();
    };
    let (lo, hi) = (b.lo.map(|v| v as f32), b.hi.map(|v| v as f32));
    seen.points(object)
        .filter(|g| (0..3).all(|k| g[k] >= lo[k] && g[k] <= hi[k]))
        .map(f)
        .collect()
}

/// One object's points as seen from a grasp, only those near some boxes.
///
/// Each box's bounding box in the object frame (centre moved, half extents
/// through |R|) is cut to the object's box; an object that none reaches is
/// skipped, and a point in none of them costs a few compares and is not
/// moved into the grasp frame (f32).
struct SeenFromGrasp {
    near: Vec<([f32; 3], [f32; 3])>,
    rotation: nalgebra::Matrix3<f32>,
    translation: Vector3<f32>,
}

impl SeenFromGrasp {
    /// `None` when no box reaches the object's box.
    fn new(world_from_grasp: &Isometry3<f64>, boxes: &[GraspBox], object: &Obstacle<'_>) -> Option<Self> {
        let object_from_grasp = object.world_from_object.inverse() * world_from_grasp;
        let abs_rotation = object_from_grasp.rotation.to_rotation_matrix().into_inner().abs();
        let near: Vec<([f32; 3], [f32; 3])> = boxes
            .iter()
            .filter_map(|b| {
                let centre = object_from_grasp * Point3::from((b.lo + b.hi) / 2.0);
                let half = abs_rotation * ((b.hi - b.lo) / 2.0);
                let lo = (centre.coords - half).sup(object.extent_min_m);
                let hi = (centre.coords + half).inf(object.extent_max_m);
                (0..3)
                    .all(|k| lo[k] <= hi[k])
                    .then(|| (lo.map(|v| v as f32).into(), hi.map(|v| v as f32).into()))
            })
            .collect();
        if near.is_empty() {
            return None;
        }
        let grasp_from_object = object_from_grasp.inverse();
        Some(Self {
            near,
            rotation: grasp_from_object
                .rotation
                .to_rotation_matrix()
                .into_inner()
                .map(|v| v as f32),
            translation: grasp_from_object.translation.vector.map(|v| v as f32),
        })
    }

    /// The object's points near a box, in the grasp frame.
    fn points<'a>(&'a self, object: &'a Obstacle<'_>) -> impl Iterator<Item = [f32; 3]> + 'a {
        let (r, t) = (&self.rotation, &self.translation);
        object
            .points
            .iter()
            .filter(|p| {
                self.near
                    .iter()
                    .any(|(lo, hi)| (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k]))
            })
            .map(move |p| {
                [
                    r[(0, 0)] * p[0] + r[(0, 1)] * p[1] + r[(0, 2)] * p[2] + t.x,
                    r[(1, 0)] * p[0] + r[(1, 1)] * p[1] + r[(1, 2)] * p[2] + t.y,
                    r[(2, 0)] * p[0] + r[(2, 1)] * p[1] + r[(2, 2)] * p[2] + t.z,
                ]
            })
    }
}

/// At least `min_points` of `object`'s points inside one of `boxes`.
fn hits_object(
    world_from_grasp: &Isometry3<f64>,
    boxes: &[GraspBox],
    boxes_f32: &[([f32; 3], [f32; 3])],
    min_points: usize,
    object: &Obstacle<'_>,
) -> bool {
    let Some(seen) = SeenFromGrasp::new(world_from_grasp, boxes, object) else {
        return false;
    };
    let enough = min_points.max(1);
    seen.points(object)
        .filter(|g| {
            boxes_f32
                .iter()
                .any(|(lo, hi)| (0..3).all(|k| g[k] >= lo[k] && g[k] <= hi[k]))
        })
        .take(enough)
        .count()
        >= enough
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;
    use crate::decode::test_support::*;

    #[test]
    fn a_free_grasp_around_a_box_passes_and_a_neighbour_under_a_pad_stops_it() {
        let (hand, table) = (HandConfig::default(), table_at(0.0));
        // A 4 cm wide, 6 cm tall box; grasp 2 cm below its top, 4 cm wide
        // (the pads open to 6 cm with the clearance).
        let object = block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]);
        let grasp = top_down(0.0, 0.0, 0.04);
        assert!(!collides(&grasp, 0.04, &hand, &table, &object));
        // 1 cm wide (the pads open to 3 cm), the pads land on the box itself.
        assert!(collides(&grasp, 0.01, &hand, &table, &object));
        // A neighbour in the right pad's path.
        let mut scene = object.clone();
        scene.extend(block([0.035, -0.02, 0.0], [0.07, 0.02, 0.06]));
        assert!(collides(&grasp, 0.04, &hand, &table, &scene));
        // A neighbour from 5 cm out is hit by a 4.5 cm grasp only because
        // the pads open 2 cm wider than the grasp (then 2 cm more on the way in).
        let mut scene = object.clone();
        scene.extend(block([0.05, -0.02, 0.0], [0.085, 0.02, 0.06]));
        assert!(collides(&grasp, 0.045, &hand, &table, &scene));
        let tight = HandConfig {
            opening_clearance_m: 0.0,
            ..hand.clone()
        };
        assert!(!collides(&grasp, 0.045, &tight, &table, &scene));
        // The same neighbour 10 cm away is no obstacle.
        let mut far = object;
        far.extend(block([0.12, -0.02, 0.0], [0.16, 0.02, 0.06]));
        assert!(!collides(&grasp, 0.04, &hand, &table, &far));
    }

    #[test]
    fn the_palm_and_the_approach_count_and_stray_points_do_not() {
        let (hand, table) = (HandConfig::default(), table_at(0.0));
        let grasp = top_down(0.0, 0.0, 0.04);
        // A shelf over the grasp, 25 cm above the fingertips: only the swept
        // approach passes through it (the palm ends 20.8 cm above them).
        let shelf = block([-0.05, -0.05, 0.29], [0.05, 0.05, 0.295]);
        assert!(collides(&grasp, 0.06, &hand, &table, &shelf));
        let short = HandConfig {
            approach_m: 0.0,
            ..hand.clone()
        };
        assert!(!collides(&grasp, 0.06, &short, &table, &shelf));
        // Two stray readings inside the right pad (4 cm wide: the pads open
        // to 6 cm) are below min_points; three are not.
        let mut stray = vec![[0.035f32, 0.0, 0.05], [0.036, 0.0, 0.06]];
        assert!(!collides(&grasp, 0.04, &hand, &table, &stray));
        stray.push([0.034, 0.005, 0.07]);
        assert!(collides(&grasp, 0.04, &hand, &table, &stray));
        let off = HandConfig {
            enabled: false,
            ..hand
        };
        let object = block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]);
        assert!(!collides(&grasp, 0.03, &off, &table, &object));
    }

    /// A flat object beside a taller one whose box, not its points, reaches
    /// over the grasp: the hand is free all the way in, but where the
    /// approach starts the palm is inside that box, where the robot-bridge
    /// would refuse it.
    #[test]
    fn where_the_approach_starts_the_hand_keeps_out_of_a_taller_neighbours_box() {
        let (hand, table, gripper) = (HandConfig::default(), table_at(0.0), Gripper::default());
        let identity = Isometry3::identity();
        let flat = block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.01]);
        // The neighbour: a 30 cm wall 16 cm out and a strip along the table
        // from 7.5 cm out (the pre-shaped palm spans 7 cm each side).
        let mut wall = block([0.16, -0.05, 0.0], [0.17, 0.05, 0.30]);
        wall.extend(block([0.075, -0.05, 0.0], [0.17, 0.05, 0.005]));
        let own = framed(flat);
        let check = |hand: &HandConfig, neighbour: Vec<[f32; 3]>| {
            let neighbour = framed(neighbour);
            let objects = [obstacle_of(&identity, &own), obstacle_of(&identity, &neighbour)];
            hand_collision(
                &top_down(0.0, 0.0, 0.005),
                0.06,
                &gripper,
                hand,
                &table,
                &objects,
                Some(0),
            )
        };
        assert_eq!(check(&hand, wall.clone()), Some(Collision::Object(1)));
        // The points alone: free.
        let points_only = HandConfig {
            pregrasp_boxes: false,
            ..hand.clone()
        };
        assert_eq!(check(&points_only, wall.clone()), None);
        // Without the margin the palm stops 5 mm short of the box.
        let bare = HandConfig {
            pregrasp_box_margin_m: 0.0,
            ..hand.clone()
        };
        assert_eq!(check(&bare, wall.clone()), None);
        // A neighbour lower than where the approach starts is no obstacle.
        let mut low = block([0.16, -0.05, 0.0], [0.17, 0.05, 0.06]);
        low.extend(block([0.075, -0.05, 0.0], [0.17, 0.05, 0.005]));
        assert_eq!(check(&hand, low), None);
        // Nor is the grasp's own box: the same wall as the grasped object.
        let alone = framed(wall);
        let lone_grasp = top_down(0.0, 0.0, 0.005);
        let objects = [obstacle_of(&identity, &alone)];
        assert_eq!(
            hand_collision(&lone_grasp, 0.06, &gripper, &hand, &table, &objects, Some(0)),
            None
        );
    }

    /// The box test against a turned box: a hand box 1 cm from a box turned
    /// 45 degrees about z is inside the turned box's own bounds but clear of
    /// the box itself.
    #[test]
    fn boxes_turned_against_each_other_meet_only_where_they_overlap() {
        let corner = Vector3::repeat(0.05);
        let (lo, hi) = (-corner, corner);
        let turned = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_4),
        );
        let object = Obstacle {
            world_from_object: &turned,
            extent_min_m: &lo,
            extent_max_m: &hi,
            points: &[],
        };
        let unit = GraspBox {
            lo: Vector3::repeat(-0.01),
            hi: Vector3::repeat(0.01),
        };
        // The turned box reaches 7.07 cm along x; its bounds 7.07 along y too.
        let at = |x: f64, y: f64| Isometry3::translation(x, y, 0.0);
        assert!(meets_box(&at(0.075, 0.0), &[unit], &object));
        assert!(!meets_box(&at(0.085, 0.0), &[unit], &object));
        // Near the bounds' corner (6 cm, 6 cm) but outside the turned box.
        assert!(!meets_box(&at(0.065, 0.065), &[unit], &object));
        assert!(meets_box(&at(0.03, 0.03), &[unit], &object));
        // The hand box turned 45 degrees about x reaches 1.41 cm up and
        // down: it meets the box's top (5 cm) from 6.41 cm up, not above.
        let tilted = |z: f64| {
            Isometry3::from_parts(
                Translation3::new(0.0, 0.0, z),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_4),
            )
        };
        assert!(meets_box(&tilted(0.063), &[unit], &object));
        assert!(!meets_box(&tilted(0.066), &[unit], &object));
    }

    #[test]
    fn the_fingers_reach_back_to_the_palm_and_the_palm_spans_the_linkage() {
        let (hand, table) = (HandConfig::default(), table_at(0.0));
        // A 4 cm wide, 9 cm tall box grasped 3 cm above the table: its top
        // is 6 cm behind the fingertips, between the 2F-140's fingers; a
        // hand whose palm began behind its 4 cm pads would meet it.
        let tall = block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.09]);
        let grasp = top_down(0.0, 0.0, 0.03);
        assert!(!collides(&grasp, 0.04, &hand, &table, &tall));
        let short = HandConfig {
            finger_length_m: 0.0,
            ..hand.clone()
        };
        assert!(collides(&grasp, 0.04, &short, &table, &tall));
        // 12 cm tall, its top reaches the palm.
        let taller = block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.12]);
        assert!(collides(&grasp, 0.04, &hand, &table, &taller));

        // A neighbour 12 cm tall, 5.5 cm out along the closing direction:
        // clear of the pads (open to 8 cm on the way in), but under the
        // linkage, which spans 14 cm at any opening; turned a quarter turn,
        // the grasp passes it.
        let gripper = Gripper::default();
        let identity = Isometry3::identity();
        let target = framed(block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]));
        let tall_neighbour = framed(block([0.055, -0.02, 0.0], [0.08, 0.02, 0.12]));
        let objects = [
            obstacle_of(&identity, &target),
            obstacle_of(&identity, &tall_neighbour),
        ];
        let hit = |grasp: &Isometry3<f64>, hand: &HandConfig| {
            hand_collision(grasp, 0.04, &gripper, hand, &table, &objects, Some(0))
        };
        assert_eq!(hit(&grasp, &hand), Some(Collision::Object(1)));
        let narrow = HandConfig {
            palm_min_span_m: 0.0,
            ..hand.clone()
        };
        assert_eq!(hit(&grasp, &narrow), None);
        let turned = grasp * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
        assert_eq!(hit(&turned, &hand), None);
    }

    /// A 640 x 480 camera 1 m above the origin looking straight down.
    fn overhead_view() -> FieldOfView {
        FieldOfView {
            world_from_camera: crate::geometry::camera_looking_at(
                Vector3::new(0.0, 0.0, 1.0),
                Vector3::zeros(),
            ),
            intrinsics: crate::sensor::Intrinsics {
                fx: 600.0,
                fy: 600.0,
                cx: 319.5,
                cy: 239.5,
            },
            width: 640,
            height: 480,
        }
    }

    #[test]
    fn pads_past_the_image_border_are_out_of_view() {
        let (hand, gripper, view) = (HandConfig::default(), Gripper::default(), overhead_view());
        // Image columns run along world x: a point d below the camera is
        // seen out to x = 320 / 600 d (the border is half a pixel past the
        // last centre), rows along y out to 240 / 600 d.
        let seen_x = |height: f64| 320.0 / 600.0 * (1.0 - height);
        assert!(view.contains(&Point3::new(seen_x(0.05) - 1e-3, 0.0, 0.05)));
        assert!(!view.contains(&Point3::new(seen_x(0.05) + 1e-3, 0.0, 0.05)));
        assert!(!view.contains(&Point3::new(0.0, 240.0 / 600.0 * 0.95 + 1e-3, 0.05)));
        assert!(!view.contains(&Point3::new(0.0, 0.0, 1.5)), "behind the camera");
        // A top-down grasp closing along x, 4 cm wide: the pads open to 6 cm
        // and are 1 cm thick, so they reach 4 cm from the centre; fingertips
        // 5 cm above the table, the pads 4 cm up from there, where the
        // border is nearest.
        let out = |x: f64| hand_out_of_view(&top_down(x, 0.0, 0.05), 0.04, &gripper, &hand, &view);
        assert!(!out(0.0));
        assert!(!out(seen_x(0.09) - 0.04 - 2e-3));
        assert!(out(seen_x(0.09) - 0.04 + 2e-3));
        assert!(out(-(seen_x(0.09) - 0.04 + 2e-3)));
        // Closing along y there instead: the pads reach only 1.35 cm (half
        // the finger width) along x.
        let turned = |x: f64| {
            let mut g = top_down(x, 0.0, 0.05);
            g.rotation =
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2) * g.rotation;
            hand_out_of_view(&g, 0.04, &gripper, &hand, &view)
        };
        assert!(!turned(seen_x(0.09) - 0.0135 - 2e-3));
        assert!(turned(seen_x(0.09) - 0.0135 + 2e-3));
    }

    #[test]
    fn points_held_in_a_rotated_object_frame_give_the_same_answers() {
        let (hand, table) = (HandConfig::default(), table_at(0.0));
        let world_from_object = Isometry3::from_parts(
            Translation3::new(0.3, -0.2, 0.01),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 1.3),
        );
        let as_obstacle = |world: &[[f32; 3]]| -> Framed {
            let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
            let local: Vec<[f32; 3]> = world
                .iter()
                .map(|p| {
                    let w = Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
                    let l = world_from_object.inverse_transform_point(&w).coords;
                    lo = lo.inf(&l);
                    hi = hi.sup(&l);
                    [l.x as f32, l.y as f32, l.z as f32]
                })
                .collect();
            (local, lo, hi)
        };
        let grasp = top_down(0.0, 0.0, 0.04);
        let mut scene = block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]);
        scene.extend(block([0.035, -0.02, 0.0], [0.07, 0.02, 0.06]));
        let framed = as_obstacle(&scene);
        let obstacle = obstacle_of(&world_from_object, &framed);
        let gripper = Gripper::default();
        for (width, want) in [(0.04, true), (0.01, true)] {
            assert_eq!(
                hand_collides(&grasp, width, &gripper, &hand, &table, &[obstacle], Some(0)),
                want
            );
            assert_eq!(collides(&grasp, width, &hand, &table, &scene), want);
        }
        // Apart, each is its own obstacle: 4 cm wide the hand hits the
        // neighbour (the second), 1 cm wide the box itself (the first).
        let own = as_obstacle(&block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]));
        let neighbour = as_obstacle(&block([0.035, -0.02, 0.0], [0.07, 0.02, 0.06]));
        let both = [
            obstacle_of(&world_from_object, &own),
            obstacle_of(&world_from_object, &neighbour),
        ];
        let hit = |width: f64| hand_collision(&grasp, width, &gripper, &hand, &table, &both, Some(0));
        assert_eq!(hit(0.04), Some(Collision::Object(1)));
        assert_eq!(hit(0.01), Some(Collision::Object(0)));
        // The box alone, 4 cm wide: free in either frame.
        let single = block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]);
        let framed = as_obstacle(&single);
        let alone = obstacle_of(&world_from_object, &framed);
        assert!(!hand_collides(
            &grasp,
            0.04,
            &gripper,
            &hand,
            &table,
            &[alone],
            Some(0)
        ));
        assert!(hand_collides(
            &grasp,
            0.01,
            &gripper,
            &hand,
            &table,
            &[alone],
            Some(0)
        ));
    }

    #[test]
    fn only_the_grasps_own_object_may_lie_between_the_pads() {
        let (hand, table, gripper) = (HandConfig::default(), table_at(0.0), Gripper::default());
        let identity = Isometry3::identity();
        // A 4 cm box, grasped 2 cm below its top, 6 cm wide (the pads open
        // to 8 cm); a flat object lying across its top: between the pads,
        // clear of the pads and of the palm.
        let target = framed(block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]));
        let on_top = framed(block([-0.02, -0.01, 0.065], [0.02, 0.01, 0.075]));
        let grasp = top_down(0.0, 0.0, 0.04);
        let objects = [obstacle_of(&identity, &target), obstacle_of(&identity, &on_top)];
        let hit = |own| hand_collision(&grasp, 0.06, &gripper, &hand, &table, &objects, own);
        assert_eq!(hit(Some(0)), Some(Collision::Object(1)));
        // Seen as one object with the box, the hand closes on both: allowed.
        let merged = framed([target.0.clone(), on_top.0.clone()].concat());
        let collides = |objects: &[Obstacle<'_>], own| {
            hand_collides(&grasp, 0.06, &gripper, &hand, &table, objects, own)
        };
        let one = [obstacle_of(&identity, &merged)];
        assert!(!collides(&one, Some(0)));
        // Without a known own object, every object's points count there.
        assert!(collides(&one, None));
        // The flat object 5 cm aside, clear of the pads' paths: no collision.
        let aside = framed(block([-0.02, 0.05, 0.065], [0.02, 0.07, 0.075]));
        assert!(!collides(
            &[obstacle_of(&identity, &target), obstacle_of(&identity, &aside)],
            Some(0)
        ));
    }

    #[test]
    fn pads_below_the_table_collide() {
        let hand = HandConfig::default();
        // Fingertips 1 cm under the table top.
        let grasp = top_down(0.0, 0.0, -0.01);
        assert!(collides(&grasp, 0.06, &hand, &table_at(0.0), &[]));
        let gripper = Gripper::default();
        assert_eq!(
            hand_collision(&grasp, 0.06, &gripper, &hand, &table_at(0.0), &[], None),
            Some(Collision::Table)
        );
        assert!(!collides(&grasp, 0.06, &hand, &table_at(-0.05), &[]));
    }
}
