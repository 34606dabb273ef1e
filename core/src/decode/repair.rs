//! Second chances for a grasp the hand check refused, and small
//! improvements to one it passed.
//!
//! A grasp refused because the hand would land on its own object (the first
//! thing [`hand_collision`](super::hand_collision) finds; not the table, not a neighbour) gets one
//! more chance ([`fit_opening`]): the opening is re-fitted to the object's
//! points between the pads' paths (centred on them, `fit_clearance_m` of
//! air each side, never narrower than asked), and the re-fitted grasp is
//! checked again, neighbours and table included. The network places the
//! grasp; the points say how far to open.
//!
//! A grasp refused because the hand would hit a *neighbour*, or its own
//! object with no opening within the stroke that clears it (an elongated
//! object grasped lengthwise), gets another kind of chance ([`turn_away`]):
//! turned about its approach axis by each of
//! `HandConfig::neighbour_turns_deg` in turn, its opening re-fitted to its
//! object's points, the first turn that passes the check is kept. The
//! network never scored that angle, so the pipeline ranks such grasps after
//! every grasp that passed as planned: they are tried only when nothing
//! else is left (in piles, where touching objects refuse most grasps).
//!
//! A grasp that passes may be squared to the surfaces its pads would meet
//! ([`squaring_turn`]) or pushed a little deeper ([`deepen`]).

use nalgebra::{Isometry3, Vector3};

use super::collision::{Obstacle, points_inside};
use super::hand::{GraspBox, HandConfig, finger_reach, gap_box, widen};
use crate::gripper::Gripper;
use crate::segment::TablePlane;

/// The grasp re-fitted to `object`'s points that lie in the pads' paths
/// (across the pads, from the fingertips back over the pad depth and the
/// approach): moved along the closing direction to their middle and opened
/// to their extent plus `fit_clearance_m` each side, ignoring up to
/// `min_points - 1` points at either end as the check does. `None` when
/// fewer than `min_points` lie there (the pads were not the problem), when
/// the opening would pass the stroke, or when the middle lies outside the
/// original opening (that would be another grasp). Returns the new pose
/// and opening; check it with [`hand_collides`](super::hand_collides) before use.
pub fn fit_opening(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    object: &Obstacle<'_>,
) -> Option<(Isometry3<f64>, f64)> {
    let mut across = points_inside(world_from_grasp, &pads_paths(gripper, hand), object, |g| g[0]);
    fit_across(world_from_grasp, &mut across, width_m, gripper, hand)
}

/// The pads' paths, as wide as the stroke (wider than that, no fit):
/// across the pads, from the fingertips back over the pad depth and the
/// approach, grasp frame.
fn pads_paths(gripper: &Gripper, hand: &HandConfig) -> GraspBox {
    let half_pad_y = gripper.finger_width_m / 2.0;
    GraspBox {
        lo: Vector3::new(
            -gripper.max_width_m,
            -half_pad_y,
            -(finger_reach(gripper, hand) + hand.approach_m),
        ),
        hi: Vector3::new(gripper.max_width_m, half_pad_y, 0.0),
    }
}

/// [`fit_opening`] given the points in the pads' paths (`across`: each
/// one's coordinate along the closing direction).
fn fit_across(
    world_from_grasp: &Isometry3<f64>,
    across: &mut [f32],
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
) -> Option<(Isometry3<f64>, f64)> {
    if across.len() < hand.min_points.max(1) {
        return None;
    }
    let (lo, hi) = trimmed_range(across, hand.min_points.saturating_sub(1));
    let middle = (lo + hi) / 2.0;
    let width = (hi - lo + 2.0 * hand.fit_clearance_m).max(width_m);
    if width > gripper.max_width_m || middle.abs() > width_m / 2.0 {
        return None;
    }
    let moved = world_from_grasp * nalgebra::Translation3::new(middle, 0.0, 0.0);
    Some((moved, width))
}

/// An object's points that the pads' paths of a grasp turned by any angle
/// about its approach can hold, in the grasp frame (x, y): those within the
/// paths' depth and their corners' distance from the approach axis. Moved
/// into the grasp frame once for all the turns [`turn_away`] tries.
struct AroundApproach {
    paths: GraspBox,
    near: Vec<[f32; 2]>,
}

impl AroundApproach {
    fn new(
        world_from_grasp: &Isometry3<f64>,
        gripper: &Gripper,
        hand: &HandConfig,
        object: &Obstacle<'_>,
    ) -> Self {
        let paths = pads_paths(gripper, hand);
        let reach = paths
            .hi
            .x
            .abs()
            .max(paths.lo.x.abs())
            .hypot(paths.hi.y.abs().max(paths.lo.y.abs()));
        let cylinder = GraspBox {
            lo: Vector3::new(-reach, -reach, paths.lo.z),
            hi: Vector3::new(reach, reach, paths.hi.z),
        };
        let near = points_inside(world_from_grasp, &cylinder, object, |g| [g[0], g[1]]);
        Self { paths, near }
    }

    /// [`fit_opening`] of the grasp turned by `turn` (rad) about its
    /// approach, `turned` its pose; `along` is scratch space, kept across
    /// turns.
    #[allow(clippy::too_many_arguments)]
    fn fit(
        &self,
        along: &mut Vec<f32>,
        turned: &Isometry3<f64>,
        turn: f64,
        width_m: f64,
        gripper: &Gripper,
        hand: &HandConfig,
    ) -> Option<(Isometry3<f64>, f64)> {
        let (sin, cos) = (turn.sin() as f32, turn.cos() as f32);
        let (lo, hi) = (self.paths.lo.map(|v| v as f32), self.paths.hi.map(|v| v as f32));
        // Every point is written and only those in the paths are kept (the
        // count advances on them): no branch on the test, which follows no
        // pattern a predictor learns. Only `along[..kept]` is read, so what
        // an earlier turn left beyond it needs no clearing.
        along.resize(self.near.len(), 0.0);
        let mut kept = 0;
        for &[x, y] in &self.near {
            let (a, side) = (cos * x + sin * y, cos * y - sin * x);
            along[kept] = a;
            kept += usize::from((a >= lo.x) & (a <= hi.x) & (side >= lo.y) & (side <= hi.y));
        }
        fit_across(turned, &mut along[..kept], width_m, gripper, hand)
    }
}

/// The `skip`-th smallest and `skip`-th largest of `values` (0: the
/// extremes; `skip` is held to the middle): for a small `skip` (the hand
/// check's default is 2) in one pass that keeps the `skip + 1` least and
/// greatest values seen, else by two selections rather than a sort, which
/// reorder `values`. `values` must not be empty and holds no NaN.
fn trimmed_range(values: &mut [f32], skip: usize) -> (f64, f64) {
    let last = values.len() - 1;
    let skip = skip.min(last / 2);
    if skip < TRACKED {
        return tracked_range(values, skip);
    }
    let (_, &mut lo, upper) = values.select_nth_unstable_by(skip, f32::total_cmp);
    let hi = if last - skip == skip {
        lo
    } else {
        *upper
            .select_nth_unstable_by(last - 2 * skip - 1, f32::total_cmp)
            .1
    };
    (f64::from(lo), f64::from(hi))
}

/// Order statistics [`trimmed_range`] reads in one pass, at most.
const TRACKED: usize = 8;

/// [`trimmed_range`] for `skip < TRACKED`: the `skip + 1` least values
/// seen kept in order (as the greatest), each value compared with the
/// last kept one first; past the first few, a value rarely enters.
fn tracked_range(values: &[f32], skip: usize) -> (f64, f64) {
    let k = skip + 1;
    let mut least = [f32::INFINITY; TRACKED];
    let mut greatest = [f32::NEG_INFINITY; TRACKED];
    for &v in values {
        if v < least[k - 1] {
            let mut i = k - 1;
            while i > 0 && least[i - 1] > v {
                least[i] = least[i - 1];
                i -= 1;
            }
            least[i] = v;
        }
        if v > greatest[k - 1] {
            let mut i = k - 1;
            while i > 0 && greatest[i - 1] < v {
                greatest[i] = greatest[i - 1];
                i -= 1;
            }
            greatest[i] = v;
        }
    }
    (f64::from(least[k - 1]), f64::from(greatest[k - 1]))
}

/// The grasp turned about its approach axis away from a neighbour: for
/// each of `hand.neighbour_turns_deg` in order, the turned grasp, its
/// opening re-fitted to `object`'s points ([`fit_opening`]; as it was
/// where they give no fit), the first that `passes` (the hand check).
/// Returns the new pose and opening; `None` when no turn passes.
pub fn turn_away(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    object: &Obstacle<'_>,
    mut passes: impl FnMut(&Isometry3<f64>, f64) -> bool,
) -> Option<(Isometry3<f64>, f64)> {
    if hand.neighbour_turns_deg.is_empty() {
        return None;
    }
    let around = AroundApproach::new(world_from_grasp, gripper, hand, object);
    let mut along = Vec::new();
    hand.neighbour_turns_deg.iter().find_map(|deg| {
        let turn = deg.to_radians();
        let turned = world_from_grasp * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn);
        let (pose, width) = around
            .fit(&mut along, &turned, turn, width_m, gripper, hand)
            .unwrap_or((turned, width_m));
        passes(&pose, width).then_some((pose, width))
    })
}

/// The grasp pushed `hand.deepen_m` further along its approach, else half
/// as far: the first of the two whose pads stay `table_clearance_m` above
/// `table` and that `passes` (the hand check). `None` when neither does
/// (or `deepen_m` is 0): keep the grasp as it was.
pub fn deepen(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    table: &TablePlane,
    table_clearance_m: f64,
    passes: impl FnMut(&Isometry3<f64>) -> bool,
) -> Option<Isometry3<f64>> {
    if hand.deepen_m <= 0.0 {
        return None;
    }
    let pushes = [hand.deepen_m, hand.deepen_m / 2.0];
    push_deeper(
        world_from_grasp,
        pushes,
        width_m,
        gripper,
        table,
        table_clearance_m,
        passes,
    )
}

/// How much further along its approach a grasp's fingertips would reach
/// the middle of its object's height (m; the depth [`deepen_to_middle`]
/// aims at): halfway between the highest of `object`'s points between the
/// pads (at the executor's opening, back over the fingers and the
/// approach) and the table, measured along the approach. `None` for an
/// approach more than 60 degrees off straight down (the table is not
/// under the object's far side), when no point lies between the pads, or
/// when the fingertips already reach the middle.
pub fn depth_to_middle(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    table: &TablePlane,
    object: &Obstacle<'_>,
) -> Option<f64> {
    let approach = world_from_grasp.rotation * Vector3::z();
    let descent = -table.normal.dot(&approach);
    if descent < 0.5 {
        return None;
    }
    let to_table = table.height_of(&world_from_grasp.translation.vector) / descent;
    if to_table <= 0.0 {
        return None;
    }
    let open = widen(width_m, hand.opening_clearance_m, gripper);
    let back = finger_reach(gripper, hand) + hand.approach_m;
    let column = gap_box(open, to_table, 0.0, to_table + back, gripper);
    let top = points_inside(world_from_grasp, &column, object, |g| f64::from(g[2]))
        .into_iter()
        .reduce(f64::min)?;
    let middle = (top + to_table) / 2.0;
    (middle > 0.0).then_some(middle)
}

/// A grasp whose fingertips stop above the middle of its object's height
/// ([`depth_to_middle`]) pushed towards it, at most
/// `hand.deepen_to_middle_m`, else half as far: the first of the two whose
/// pads stay `table_clearance_m` above `table` and that `passes` (the hand
/// check). `None` when neither does, when the push would be no deeper
/// than [`deepen`]'s (`hand.deepen_m`), or when it is off (0).
#[allow(clippy::too_many_arguments)]
pub fn deepen_to_middle(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    table: &TablePlane,
    table_clearance_m: f64,
    object: &Obstacle<'_>,
    passes: impl FnMut(&Isometry3<f64>) -> bool,
) -> Option<Isometry3<f64>> {
    if hand.deepen_to_middle_m <= 0.0 {
        return None;
    }
    let push = depth_to_middle(world_from_grasp, width_m, gripper, hand, table, object)?
        .min(hand.deepen_to_middle_m);
    if push <= hand.deepen_m {
        return None;
    }
    push_deeper(
        world_from_grasp,
        [push, push / 2.0],
        width_m,
        gripper,
        table,
        table_clearance_m,
        passes,
    )
}

/// The first of `pushes` (m along the approach) whose pads stay
/// `table_clearance_m` above `table` and that `passes`.
fn push_deeper(
    world_from_grasp: &Isometry3<f64>,
    pushes: [f64; 2],
    width_m: f64,
    gripper: &Gripper,
    table: &TablePlane,
    table_clearance_m: f64,
    mut passes: impl FnMut(&Isometry3<f64>) -> bool,
) -> Option<Isometry3<f64>> {
    let closing = world_from_grasp.rotation * Vector3::x();
    let approach = world_from_grasp.rotation * Vector3::z();
    let lowest = super::grasp::lowest_pad_corner(&closing, &approach, width_m, gripper, table);
    pushes.into_iter().find_map(|d| {
        let pose = nalgebra::Translation3::from(approach * d) * world_from_grasp;
        let clear = table.height_of(&pose.translation.vector) + lowest >= table_clearance_m;
        (clear && passes(&pose)).then_some(pose)
    })
}

/// Fewest points a contact patch is fitted to.
const PATCH_MIN_POINTS: usize = 6;

/// How the surface each pad would meet runs across the pad, as `object`'s
/// points show it: of the points between the pads (across the pad width,
/// over the pad depth back from the fingertips, within the opening the
/// executor uses), those within `hand.patch_slab_m` of the one nearest each
/// pad, fitted with a plane `x = a y + b z + c` in the grasp frame; returns
/// `a` (the surface's run along the closing direction per metre across
/// it: 0 when square to the closing direction about the approach axis).
/// `None` for a side with fewer than six such points (not seen). Index 0:
/// the pad at -x.
pub fn contact_slopes(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    object: &Obstacle<'_>,
) -> [Option<f64>; 2] {
    let open = widen(width_m, hand.opening_clearance_m, gripper);
    let between = gap_box(open, 0.0, 0.0, gripper.finger_depth_m, gripper);
    let inside: Vec<Vector3<f64>> = points_inside(world_from_grasp, &between, object, |g| {
        Vector3::new(f64::from(g[0]), f64::from(g[1]), f64::from(g[2]))
    });
    [-1.0, 1.0].map(|side: f64| {
        let nearest = inside
            .iter()
            .map(|p| side * p.x)
            .fold(f64::NEG_INFINITY, f64::max);
        let patch = || {
            inside
                .iter()
                .filter(|p| side * p.x >= nearest - hand.patch_slab_m)
        };
        if patch().count() < PATCH_MIN_POINTS {
            return None;
        }
        let (mut normal, mut rhs) = (nalgebra::Matrix3::<f64>::zeros(), Vector3::zeros());
        for p in patch() {
            let v = Vector3::new(p.y, p.z, 1.0);
            normal += v * v.transpose();
            rhs += v * p.x;
        }
        Some((normal.try_inverse()? * rhs)[0])
    })
}

/// The turn about the approach axis (rad) that squares the grasp to the
/// surfaces its pads would meet ([`contact_slopes`]): `-atan` of their mean
/// slope, when every seen side turns the same way and the turn lies
/// within `hand.square_turn_deg`; `None` otherwise (nothing seen, sides that
/// disagree, a turn under a degree, or one too large to trust).
pub fn squaring_turn(slopes: [Option<f64>; 2], hand: &HandConfig) -> Option<f64> {
    let seen: Vec<f64> = slopes.into_iter().flatten().collect();
    if seen.is_empty() || !(seen.iter().all(|&a| a > 0.0) || seen.iter().all(|&a| a < 0.0)) {
        return None;
    }
    let turn = -(seen.iter().sum::<f64>() / seen.len() as f64).atan();
    (turn.abs() >= 1f64.to_radians() && turn.abs() <= hand.square_turn_deg.to_radians()).then_some(turn)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;
    use crate::decode::collision::{Collision, hand_collision};
    use crate::decode::test_support::*;

    /// The selections give what sorting gives: the `skip`-th value from
    /// each end, `skip` held to the middle, duplicates included.
    #[test]
    fn trimmed_range_matches_a_sort() {
        let mut state = 7u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 24) as f32 / 16.0 - 8.0
        };
        for len in 1..40 {
            for skip in [0, 1, 2, 3, 7, 8, 19, 25, 100] {
                let values: Vec<f32> = (0..len).map(|_| next()).collect();
                let mut sorted = values.clone();
                sorted.sort_by(f32::total_cmp);
                let s = skip.min((len - 1) / 2);
                let expected = (f64::from(sorted[s]), f64::from(sorted[len - 1 - s]));
                assert_eq!(
                    trimmed_range(&mut values.clone(), skip),
                    expected,
                    "{values:?} skip {skip}"
                );
            }
        }
    }

    /// The turns' re-fit from points moved once ([`AroundApproach`]) is the
    /// re-fit of each turned grasp from scratch ([`fit_opening`]).
    #[test]
    fn a_turn_refits_as_fit_opening_does() {
        let (gripper, hand) = (Gripper::default(), HandConfig::default());
        let mut state = 11u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            f64::from(state >> 8) / f64::from(1u32 << 24) - 0.5
        };
        let (lo, hi) = (Vector3::repeat(-0.2), Vector3::repeat(0.2));
        let (mut fitted, mut checked) = (0, 0);
        for _ in 0..40 {
            let world_from_object = Isometry3::new(
                Vector3::new(next(), next(), next()) * 0.2,
                Vector3::new(next(), next(), next()) * 6.0,
            );
            // A slab of an object, so that some turns fit and some do not.
            let half = Vector3::new(0.02 + 0.1 * next().abs(), 0.01 + 0.1 * next().abs(), 0.1);
            let points: Vec<[f32; 3]> = (0..600)
                .map(|_| {
                    [
                        next() * 2.0 * half.x,
                        next() * 2.0 * half.y,
                        next() * 2.0 * half.z,
                    ]
                    .map(|v| v as f32)
                })
                .collect();
            let object = Obstacle {
                world_from_object: &world_from_object,
                extent_min_m: &lo,
                extent_max_m: &hi,
                points: &points,
            };
            let world_from_grasp = world_from_object
                * Isometry3::new(
                    Vector3::new(0.02 * next(), 0.02 * next(), 0.1),
                    Vector3::new(std::f64::consts::PI + 0.3 * next(), 0.3 * next(), 6.0 * next()),
                );
            let width = 0.02 + 0.1 * next().abs();
            let around = AroundApproach::new(&world_from_grasp, &gripper, &hand, &object);
            let mut along = Vec::new();
            for &deg in &hand.neighbour_turns_deg {
                let turn = f64::to_radians(deg);
                let turned = world_from_grasp * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn);
                let fast = around.fit(&mut along, &turned, turn, width, &gripper, &hand);
                let slow = fit_opening(&turned, width, &gripper, &hand, &object);
                checked += 1;
                match (fast, slow) {
                    (None, None) => {}
                    (Some((a, wa)), Some((b, wb))) => {
                        fitted += 1;
                        assert!(
                            (a.translation.vector - b.translation.vector).norm() < 1e-5,
                            "{deg}"
                        );
                        assert!(a.rotation.angle_to(&b.rotation) < 1e-9, "{deg}");
                        assert!((wa - wb).abs() < 1e-5, "{deg}: {wa} {wb}");
                    }
                    (fast, slow) => panic!("{deg}: {fast:?} against {slow:?}"),
                }
            }
        }
        assert!(
            fitted > checked / 5 && fitted < checked,
            "{fitted} of {checked} fitted"
        );
    }

    /// `query` with the default gripper and hand on `points` (world frame)
    /// as one object framed by the identity, its box the 2 m cube.
    fn on_points<R>(points: &[[f32; 3]], query: impl FnOnce(&Gripper, &HandConfig, &Obstacle<'_>) -> R) -> R {
        let identity = Isometry3::identity();
        let (lo, hi) = (Vector3::repeat(-1.0), Vector3::repeat(1.0));
        let obstacle = Obstacle {
            world_from_object: &identity,
            extent_min_m: &lo,
            extent_max_m: &hi,
            points,
        };
        query(&Gripper::default(), &HandConfig::default(), &obstacle)
    }

    /// [`fit_opening`] on `points` (world frame) framed by the identity.
    fn fit(grasp: &Isometry3<f64>, width: f64, points: &[[f32; 3]]) -> Option<(Isometry3<f64>, f64)> {
        on_points(points, |gripper, hand, obstacle| {
            fit_opening(grasp, width, gripper, hand, obstacle)
        })
    }

    /// [`contact_slopes`] on `points` (world frame) framed by the identity.
    fn slopes(grasp: &Isometry3<f64>, width: f64, points: &[[f32; 3]]) -> [Option<f64>; 2] {
        on_points(points, |gripper, hand, obstacle| {
            contact_slopes(grasp, width, gripper, hand, obstacle)
        })
    }

    /// The two 6 cm apart faces of a box, standing along world y, whose
    /// normals are turned `deg` about world z from world x: points every
    /// 2 mm over 4 x 5 cm of each face (z in 0.02-0.07).
    fn turned_faces(deg: f64) -> Vec<[f32; 3]> {
        let (sin, cos) = deg.to_radians().sin_cos();
        let mut points = Vec::new();
        for side in [-1.0, 1.0] {
            for i in 0..=20 {
                for k in 0..=25 {
                    let along = -0.02 + 0.002 * f64::from(i);
                    let z = 0.02 + 0.002 * f64::from(k);
                    // 3 cm out along the normal, `along` across it.
                    let (x, y) = (side * 0.03 * cos - along * sin, side * 0.03 * sin + along * cos);
                    points.push([x as f32, y as f32, z as f32]);
                }
            }
        }
        points
    }

    #[test]
    fn a_grasp_is_squared_to_faces_turned_off_its_closing_direction() {
        let hand = HandConfig::default();
        let grasp = top_down(0.0, 0.0, 0.03);
        // Faces turned 10 degrees: both sides run the same way across the pads.
        let faces = turned_faces(10.0);
        let [Some(left), Some(right)] = slopes(&grasp, 0.06, &faces) else {
            panic!("both faces are between the pads");
        };
        for a in [left, right] {
            assert!((a.abs() - 10f64.to_radians().tan()).abs() < 0.01, "{a}");
        }
        assert!(left * right > 0.0);
        let turn = squaring_turn([Some(left), Some(right)], &hand).expect("a turn");
        assert!(
            (turn.abs().to_degrees() - 10.0).abs() < 0.5,
            "{}",
            turn.to_degrees()
        );
        // Turned by it, the grasp closes square to the faces: nothing to turn.
        let turned = grasp
            * Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn),
            );
        let again = slopes(&turned, 0.06, &faces);
        assert!(
            again.iter().all(|a| a.is_some_and(|a| a.abs() < 0.01)),
            "{again:?}"
        );
        assert_eq!(squaring_turn(again, &hand), None);
        // Square faces need no turn; faces turned 25 degrees are past the
        // 15 degree limit (another grasp, not this one squared).
        assert_eq!(
            squaring_turn(slopes(&grasp, 0.06, &turned_faces(0.0)), &hand),
            None
        );
        assert_eq!(
            squaring_turn(slopes(&grasp, 0.06, &turned_faces(25.0)), &hand),
            None
        );
    }

    #[test]
    fn squaring_needs_the_seen_sides_to_agree() {
        let hand = HandConfig::default();
        let a = 8f64.to_radians().tan();
        // One side seen is enough; the turn undoes its slope.
        let one = squaring_turn([None, Some(a)], &hand).unwrap();
        assert!((one + 8f64.to_radians()).abs() < 1e-9, "{one}");
        // A wedge (the sides run opposite ways) or nothing seen: no turn.
        assert_eq!(squaring_turn([Some(-a), Some(a)], &hand), None);
        assert_eq!(squaring_turn([None, None], &hand), None);
        // Off when the limit is 0.
        let off = HandConfig {
            square_turn_deg: 0.0,
            ..HandConfig::default()
        };
        assert_eq!(squaring_turn([Some(a), Some(a)], &off), None);
    }

    #[test]
    fn an_opening_on_the_object_is_re_fitted_around_it() {
        let (hand, table) = (HandConfig::default(), table_at(0.0));
        // A 4 cm box; the grasp 1.5 cm off its middle along the closing
        // direction, opened to 4 cm: the left pad lands on the box.
        let object = block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]);
        let grasp = top_down(0.015, 0.0, 0.04);
        assert!(collides(&grasp, 0.04, &hand, &table, &object));
        let (moved, width) = fit(&grasp, 0.04, &object).expect("a re-fit");
        // Centred on the box, opened to it plus 5 mm each side.
        assert!((moved.translation.vector - Vector3::new(0.0, 0.0, 0.04)).norm() < 1e-9);
        assert!((width - 0.05).abs() < 1e-9);
        assert_eq!(moved.rotation, grasp.rotation);
        assert!(!collides(&moved, width, &hand, &table, &object));
        // Never narrower than asked.
        let (_, wide) = fit(&grasp, 0.07, &object).expect("a re-fit");
        assert!((wide - 0.07).abs() < 1e-9);
    }

    #[test]
    fn no_re_fit_past_the_stroke_off_the_opening_or_without_points() {
        // 15 cm of object between the pads' paths: past the 14 cm stroke.
        let long = block([-0.075, -0.01, 0.0], [0.075, 0.01, 0.04]);
        assert!(fit(&top_down(0.0, 0.0, 0.03), 0.05, &long).is_none());
        // The points' middle 3 cm from the grasp, opened to 4 cm: another grasp.
        let object = block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]);
        assert!(fit(&top_down(0.03, 0.0, 0.04), 0.04, &object).is_none());
        // Points only beside the pads' paths (across them): nothing to fit.
        let beside = block([-0.02, 0.03, 0.0], [0.02, 0.05, 0.06]);
        assert!(fit(&top_down(0.0, 0.0, 0.04), 0.04, &beside).is_none());
        // Two stray points in a path are below min_points, as for the check.
        assert!(
            fit(
                &top_down(0.0, 0.0, 0.04),
                0.04,
                &[[0.02, 0.0, 0.05], [0.021, 0.0, 0.05]]
            )
            .is_none()
        );
    }

    #[test]
    fn a_grasp_into_a_neighbour_turns_away_from_it() {
        let (hand, table, gripper) = (HandConfig::default(), table_at(0.0), Gripper::default());
        let identity = Isometry3::identity();
        // A 4 x 6 cm box (6 cm along y), a neighbour 1.5 cm off its side
        // along x: closing along x, 4 cm wide, the right pad comes down on it.
        let own = framed(block([-0.02, -0.03, 0.0], [0.02, 0.03, 0.06]));
        let neighbour = framed(block([0.035, -0.04, 0.0], [0.07, 0.04, 0.06]));
        let objects = [obstacle_of(&identity, &own), obstacle_of(&identity, &neighbour)];
        let grasp = top_down(0.0, 0.0, 0.04);
        let hit = |pose: &Isometry3<f64>, width: f64| {
            hand_collision(pose, width, &gripper, &hand, &table, &objects, Some(0))
        };
        assert_eq!(hit(&grasp, 0.04), Some(Collision::Object(1)));
        let (pose, width) = turn_away(&grasp, 0.04, &gripper, &hand, &objects[0], |p, w| {
            hit(p, w).is_none()
        })
        .expect("a turn");
        assert_eq!(hit(&pose, width), None);
        // The same approach and fingertips' height; the closing direction
        // turned by the first turn of the list that passes.
        let approach = |p: &Isometry3<f64>| p.rotation * Vector3::z();
        assert!((approach(&pose) - approach(&grasp)).norm() < 1e-12);
        assert!((pose.translation.z - grasp.translation.z).abs() < 1e-12);
        let turned = |deg: f64| grasp * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), deg.to_radians());
        let first = hand
            .neighbour_turns_deg
            .iter()
            .position(|&deg| {
                let c = turned(deg).rotation * Vector3::x();
                (pose.rotation * Vector3::x()).dot(&c) > 1.0 - 1e-9
            })
            .expect("one of the turns");
        assert!(hand.neighbour_turns_deg[first].abs() >= 45.0, "{first}");
        for &deg in &hand.neighbour_turns_deg[..first] {
            let fitted =
                fit_opening(&turned(deg), 0.04, &gripper, &hand, &objects[0]).unwrap_or((turned(deg), 0.04));
            assert!(hit(&fitted.0, fitted.1).is_some(), "{deg} passes too");
        }
        // Re-fitted to the box across its turned extent, never narrower.
        assert!(width >= 0.04, "{width}");
        // No turns, or none that passes: none.
        let still = HandConfig {
            neighbour_turns_deg: Vec::new(),
            ..hand.clone()
        };
        assert!(turn_away(&grasp, 0.04, &gripper, &still, &objects[0], |_, _| true).is_none());
        assert!(turn_away(&grasp, 0.04, &gripper, &hand, &objects[0], |_, _| false).is_none());
    }

    #[test]
    fn a_grasp_goes_deeper_where_the_hand_and_the_table_allow() {
        let (hand, table, gripper) = (HandConfig::default(), table_at(0.0), Gripper::default());
        let identity = Isometry3::identity();
        // A 4 x 4 cm box 13 cm tall, fingertips 6.2 cm below its top: the
        // palm (7.2 cm behind the fingertips) is 1 cm over it, so the hand
        // passes 5 mm deeper.
        let own = framed(block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.13]));
        let objects = [obstacle_of(&identity, &own)];
        let hit =
            |pose: &Isometry3<f64>| hand_collision(pose, 0.04, &gripper, &hand, &table, &objects, Some(0));
        let grasp = top_down(0.0, 0.0, 0.068);
        assert_eq!(hit(&grasp), None);
        let deeper =
            deepen(&grasp, 0.04, &gripper, &hand, &table, 0.003, |p| hit(p).is_none()).expect("deeper");
        assert!(
            (deeper.translation.z - (0.068 - hand.deepen_m)).abs() < 1e-12,
            "{deeper}"
        );
        assert!(deeper.rotation.angle_to(&grasp.rotation) < 1e-12);
        // Fingertips already 6.8 cm below the top: 5 mm more puts the palm
        // 1 mm into it, 2.5 mm leaves it 1.5 mm over.
        let grasp = top_down(0.0, 0.0, 0.062);
        let deeper =
            deepen(&grasp, 0.04, &gripper, &hand, &table, 0.003, |p| hit(p).is_none()).expect("half");
        assert!(
            (deeper.translation.z - (0.062 - hand.deepen_m / 2.0)).abs() < 1e-12,
            "{deeper}"
        );
        // Fingertips 6 mm over the table: 2.5 mm deeper leaves 3.5 mm, 5 mm
        // only 1 mm; with 4 mm required, neither.
        let low = top_down(0.0, 0.0, 0.006);
        let deeper = deepen(&low, 0.04, &gripper, &hand, &table, 0.003, |_| true).expect("half");
        assert!((deeper.translation.z - 0.0035).abs() < 1e-12, "{deeper}");
        assert!(deepen(&low, 0.04, &gripper, &hand, &table, 0.004, |_| true).is_none());
        // Off, or refused by the check: as it was.
        let off = HandConfig {
            deepen_m: 0.0,
            ..hand.clone()
        };
        assert!(deepen(&grasp, 0.04, &gripper, &off, &table, 0.003, |_| true).is_none());
        assert!(deepen(&grasp, 0.04, &gripper, &hand, &table, 0.003, |_| false).is_none());
    }

    #[test]
    fn a_grasp_goes_towards_the_middle_of_a_tall_object() {
        let (table, gripper) = (table_at(0.0), Gripper::default());
        let hand = HandConfig {
            deepen_to_middle_m: 0.04,
            ..HandConfig::default()
        };
        let identity = Isometry3::identity();
        // A 4 x 4 cm box 13 cm tall, fingertips 3 cm below its top: the
        // middle of its height is 3.5 cm further down, where the palm
        // (7.2 cm behind the fingertips) stays 7 mm over it.
        let own = framed(block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.13]));
        let objects = [obstacle_of(&identity, &own)];
        let hit =
            |pose: &Isometry3<f64>| hand_collision(pose, 0.04, &gripper, &hand, &table, &objects, Some(0));
        let grasp = top_down(0.0, 0.0, 0.10);
        let middle = depth_to_middle(&grasp, 0.04, &gripper, &hand, &table, &objects[0]).expect("above it");
        assert!((middle - 0.035).abs() < 1e-6, "{middle}");
        let deeper = deepen_to_middle(&grasp, 0.04, &gripper, &hand, &table, 0.003, &objects[0], |p| {
            hit(p).is_none()
        })
        .expect("to the middle");
        assert!((deeper.translation.z - 0.065).abs() < 1e-6, "{deeper}");
        assert_eq!(hit(&deeper), None);
        // At most deepen_to_middle_m; half as far when the full push fails.
        let short = HandConfig {
            deepen_to_middle_m: 0.02,
            ..hand.clone()
        };
        let capped = deepen_to_middle(&grasp, 0.04, &gripper, &short, &table, 0.003, &objects[0], |_| {
            true
        })
        .expect("capped");
        assert!((capped.translation.z - 0.08).abs() < 1e-6, "{capped}");
        let half = deepen_to_middle(&grasp, 0.04, &gripper, &hand, &table, 0.003, &objects[0], |p| {
            p.translation.z > 0.07
        })
        .expect("half");
        assert!((half.translation.z - 0.0825).abs() < 1e-6, "{half}");
        // Off, refused by the check, already past the middle of a 5 cm
        // box, or coming from the side: none.
        let off = HandConfig {
            deepen_to_middle_m: 0.0,
            ..hand.clone()
        };
        assert!(
            deepen_to_middle(&grasp, 0.04, &gripper, &off, &table, 0.003, &objects[0], |_| true).is_none()
        );
        assert!(
            deepen_to_middle(&grasp, 0.04, &gripper, &hand, &table, 0.003, &objects[0], |_| {
                false
            })
            .is_none()
        );
        let low = framed(block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.05]));
        let low_objects = [obstacle_of(&identity, &low)];
        let over_low = top_down(0.0, 0.0, 0.02);
        assert_eq!(
            depth_to_middle(&over_low, 0.04, &gripper, &hand, &table, &low_objects[0]),
            None
        );
        let side = Isometry3::from_parts(
            Translation3::new(-0.05, 0.0, 0.06),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2),
        );
        assert_eq!(
            depth_to_middle(&side, 0.04, &gripper, &hand, &table, &objects[0]),
            None
        );
        // No points between the pads: nothing to measure.
        let beside = top_down(0.2, 0.0, 0.10);
        assert_eq!(
            depth_to_middle(&beside, 0.04, &gripper, &hand, &table, &objects[0]),
            None
        );
    }
}
