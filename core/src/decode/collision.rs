//! Does the hand hit what the camera saw? A check of each grasp, in rank
//! order, before it is returned.
//!
//! The hand is boxes in the grasp frame (DESIGN.md: +z the approach,
//! +x the closing direction, origin midway between the fingertips), as the
//! simulator models the Robotiq 2F-140 (`sim::grasp::GripperModel`):
//!
//! - two pads, `pad_thickness_m` thick along x, the gripper's finger width
//!   along y and its finger depth along z, their inner faces half the
//!   opening from the origin; the opening is the grasp's width plus
//!   `opening_clearance_m`, as the executor opens before closing;
//! - the palm behind them, `palm_depth_m` along z, `palm_width_m` along y,
//!   spanning both pads along x;
//! - the gap between the pads, where only the grasp's own object may be.
//!
//! The boxes are checked where the hand ends and swept back along the
//! approach by `approach_m`, pre-shaped `preshape_margin_m` wider (within
//! the stroke), as a robot arrives. A grasp collides when at least
//! `min_points` of one detected object's points fall inside (one stray
//! reading is not an obstacle), or when a box corner reaches under the
//! table plane. The object's own points count in the pads and the palm:
//! pads that land on the object are a failed grasp as much as pads that
//! land on its neighbour. Another object's points count between the pads
//! too (the hand would close on it, or meet it with the palm on the way
//! down).
//!
//! A grasp refused because the hand would land on its own object (the first
//! thing [`hand_collision`] finds; not the table, not a neighbour) gets one
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

use crate::gripper::Gripper;
use crate::segment::TablePlane;
use crate::sensor::FieldOfView;

/// The hand's shape beyond the pads' contact faces, and how strictly to check.
#[derive(Debug, Clone, PartialEq)]
pub struct HandConfig {
    /// Check the hand at all (off: every grasp passes).
    pub enabled: bool,
    /// Pad thickness along the closing direction (m).
    pub pad_thickness_m: f64,
    /// How much wider than the grasp's width the pads open before closing
    /// (m, within the stroke): the executor's margin (`sim`'s
    /// `GripperModel::clearance_m`). The hand is checked at that opening.
    pub opening_clearance_m: f64,
    /// Gripper body behind the pads: depth along the approach (m).
    pub palm_depth_m: f64,
    /// Gripper body extent across the closing direction (m).
    pub palm_width_m: f64,
    /// How far back along the approach the hand is swept (m).
    pub approach_m: f64,
    /// Extra opening while approaching (m), within the stroke.
    pub preshape_margin_m: f64,
    /// Observed points inside the hand that make a collision.
    pub min_points: usize,
    /// Below this height above the table a box corner is a collision (m;
    /// negative: that far into the table).
    pub table_margin_m: f64,
    /// Re-fit a refused grasp's opening to its object's points
    /// ([`fit_opening`]) and check it again.
    pub fit_opening: bool,
    /// Air between each pad and the object's points after a re-fit (m).
    pub fit_clearance_m: f64,
    /// Rank a grasp whose pads, where the hand ends, reach outside the
    /// camera's field of view after every grasp that stays inside (depth
    /// images only: [`hand_out_of_view`]).
    pub out_of_view_last: bool,
    /// Turn a grasp about its approach axis, up to this far (degrees), to
    /// square it to the surfaces its pads would meet as seen
    /// ([`squaring_turn`]), when the turned grasp passes the check; 0: never.
    pub square_turn_deg: f64,
    /// How deep a slab of the object's points, from the point nearest each
    /// pad, stands for the surface the pad meets (m).
    pub patch_slab_m: f64,
    /// Turns about the approach axis (degrees, tried in order) for a grasp
    /// the check refused for a neighbour or its own object ([`turn_away`]);
    /// empty: none.
    pub neighbour_turns_deg: Vec<f64>,
    /// Push a grasp that passes the check this much further along its
    /// approach, or half as far, where the hand still passes and the pads
    /// stay clear of the table ([`deepen`]; m, 0: never): pads that reach
    /// lower on a tall, round object hold it below its widest section.
    pub deepen_m: f64,
}

impl Default for HandConfig {
    /// The Robotiq 2F-140 as `sim` models it; a 10 cm approach.
    fn default() -> Self {
        Self {
            enabled: true,
            pad_thickness_m: 0.01,
            opening_clearance_m: 0.02,
            palm_depth_m: 0.05,
            palm_width_m: 0.075,
            approach_m: 0.10,
            preshape_margin_m: 0.02,
            min_points: 3,
            table_margin_m: -0.002,
            fit_opening: true,
            fit_clearance_m: 0.005,
            out_of_view_last: true,
            square_turn_deg: 15.0,
            patch_slab_m: 0.006,
            // Smallest turns first, either way, up to a quarter turn.
            neighbour_turns_deg: vec![20.0, -20.0, 45.0, -45.0, 70.0, -70.0, 90.0],
            // sim/README.md: of top-down grasps stopping above the middle of
            // their object's height 0.87 held, reaching below it 0.96.
            deepen_m: 0.005,
        }
    }
}

/// An axis-aligned box in the grasp frame.
#[derive(Debug, Clone, Copy, PartialEq)]
struct GraspBox {
    lo: Vector3<f64>,
    hi: Vector3<f64>,
}

impl GraspBox {
    fn corners(&self) -> impl Iterator<Item = Vector3<f64>> + '_ {
        (0..8).map(move |i| {
            Vector3::new(
                if i & 1 == 0 { self.lo.x } else { self.hi.x },
                if i & 2 == 0 { self.lo.y } else { self.hi.y },
                if i & 4 == 0 { self.lo.z } else { self.hi.z },
            )
        })
    }
}

/// `width_m` opened `by` more, within the stroke (never narrower).
fn widen(width_m: f64, by: f64, gripper: &Gripper) -> f64 {
    (width_m + by).min(gripper.max_width_m).max(width_m)
}

/// The hand's boxes for an opening `width_m`, the fingertips at `tip_z`
/// and swept back to `tip_z - sweep` (grasp frame).
fn hand_boxes(width_m: f64, tip_z: f64, sweep: f64, gripper: &Gripper, hand: &HandConfig) -> [GraspBox; 3] {
    let (half_w, t) = (width_m / 2.0, hand.pad_thickness_m);
    let half_pad_y = gripper.finger_width_m / 2.0;
    let pad_lo_z = tip_z - gripper.finger_depth_m - sweep;
    let pad = |sign: f64| {
        let (a, b) = (sign * half_w, sign * (half_w + t));
        GraspBox {
            lo: Vector3::new(a.min(b), -half_pad_y, pad_lo_z),
            hi: Vector3::new(a.max(b), half_pad_y, tip_z),
        }
    };
    let palm_hi_z = tip_z - gripper.finger_depth_m;
    let palm = GraspBox {
        lo: Vector3::new(
            -(half_w + t),
            -hand.palm_width_m / 2.0,
            palm_hi_z - hand.palm_depth_m - sweep,
        ),
        hi: Vector3::new(half_w + t, hand.palm_width_m / 2.0, palm_hi_z),
    };
    [pad(-1.0), pad(1.0), palm]
}

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
    hand_boxes(open, 0.0, 0.0, gripper, hand)[..2]
        .iter()
        .flat_map(GraspBox::corners)
        .any(|c| !view.contains(&(world_from_grasp * Point3::from(c))))
}

/// Whether the hand, closing to `width_m` at `world_from_grasp` after its
/// approach, would hit the observed points of `obstacles` or the table.
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
    let mut boxes = hand_boxes(open, 0.0, 0.0, gripper, hand).to_vec();
    boxes.extend(hand_boxes(preshaped, -1e-3, hand.approach_m, gripper, hand));

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
    boxes.push(gap_box(open, 0.0, 0.0, gripper));
    boxes.push(gap_box(preshaped, -1e-3, hand.approach_m, gripper));
    let boxes_f32: Vec<([f32; 3], [f32; 3])> = boxes
        .iter()
        .map(|b| (b.lo.map(|v| v as f32).into(), b.hi.map(|v| v as f32).into()))
        .collect();
    obstacles
        .iter()
        .enumerate()
        .position(|(i, o)| {
            let n = if own == Some(i) { hand_only } else { boxes.len() };
            hits_object(world_from_grasp, &boxes[..n], &boxes_f32[..n], hand.min_points, o)
        })
        .map(Collision::Object)
}

/// The space between the pads for an opening `width_m`, the fingertips at
/// `tip_z` and swept back to `tip_z - sweep` (grasp frame).
fn gap_box(width_m: f64, tip_z: f64, sweep: f64, gripper: &Gripper) -> GraspBox {
    let (half_w, half_pad_y) = (width_m / 2.0, gripper.finger_width_m / 2.0);
    GraspBox {
        lo: Vector3::new(-half_w, -half_pad_y, tip_z - gripper.finger_depth_m - sweep),
        hi: Vector3::new(half_w, half_pad_y, tip_z),
    }
}

/// The grasp re-fitted to `object`'s points that lie in the pads' paths
/// (across the pads, from the fingertips back over the pad depth and the
/// approach): moved along the closing direction to their middle and opened
/// to their extent plus `fit_clearance_m` each side, ignoring up to
/// `min_points - 1` points at either end as the check does. `None` when
/// fewer than `min_points` lie there (the pads were not the problem), when
/// the opening would pass the stroke, or when the middle lies outside the
/// original opening (that would be another grasp). Returns the new pose
/// and opening; check it with [`hand_collides`] before use.
pub fn fit_opening(
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &Gripper,
    hand: &HandConfig,
    object: &Obstacle<'_>,
) -> Option<(Isometry3<f64>, f64)> {
    // The pads' paths, as wide as the stroke: wider than that, no fit.
    let half_pad_y = gripper.finger_width_m / 2.0;
    let paths = GraspBox {
        lo: Vector3::new(
            -gripper.max_width_m,
            -half_pad_y,
            -(gripper.finger_depth_m + hand.approach_m),
        ),
        hi: Vector3::new(gripper.max_width_m, half_pad_y, 0.0),
    };
    let mut across: Vec<f32> = points_inside(world_from_grasp, &paths, object)
        .iter()
        .map(|g| g[0])
        .collect();
    if across.len() < hand.min_points.max(1) {
        return None;
    }
    across.sort_by(f32::total_cmp);
    let skip = hand.min_points.saturating_sub(1).min((across.len() - 1) / 2);
    let (lo, hi) = (
        f64::from(across[skip]),
        f64::from(across[across.len() - 1 - skip]),
    );
    let middle = (lo + hi) / 2.0;
    let width = (hi - lo + 2.0 * hand.fit_clearance_m).max(width_m);
    if width > gripper.max_width_m || middle.abs() > width_m / 2.0 {
        return None;
    }
    let moved = world_from_grasp * nalgebra::Translation3::new(middle, 0.0, 0.0);
    Some((moved, width))
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
    hand.neighbour_turns_deg.iter().find_map(|deg| {
        let turned = world_from_grasp
            * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), deg.to_radians());
        let (pose, width) = fit_opening(&turned, width_m, gripper, hand, object).unwrap_or((turned, width_m));
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
    mut passes: impl FnMut(&Isometry3<f64>) -> bool,
) -> Option<Isometry3<f64>> {
    if hand.deepen_m <= 0.0 {
        return None;
    }
    let closing = world_from_grasp.rotation * Vector3::x();
    let approach = world_from_grasp.rotation * Vector3::z();
    let lowest = super::grasp::lowest_pad_corner(&closing, &approach, width_m, gripper, table);
    [hand.deepen_m, hand.deepen_m / 2.0].into_iter().find_map(|d| {
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
    let between = gap_box(open, 0.0, 0.0, gripper);
    let inside: Vec<Vector3<f64>> = points_inside(world_from_grasp, &between, object)
        .iter()
        .map(|g| Vector3::new(f64::from(g[0]), f64::from(g[1]), f64::from(g[2])))
        .collect();
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

/// `object`'s points inside `b`, in the grasp frame (f32); none when `b`
/// does not reach the object's box.
fn points_inside(world_from_grasp: &Isometry3<f64>, b: &GraspBox, object: &Obstacle<'_>) -> Vec<[f32; 3]> {
    let Some(seen) = SeenFromGrasp::new(world_from_grasp, &[*b], object) else {
        return Vec::new();
    };
    let (lo, hi) = (b.lo.map(|v| v as f32), b.hi.map(|v| v as f32));
    seen.points(object)
        .filter(|g| (0..3).all(|k| g[k] >= lo[k] && g[k] <= hi[k]))
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

    fn table_at(z: f64) -> TablePlane {
        TablePlane {
            normal: Vector3::z(),
            offset_m: -z,
            support: 1.0,
        }
    }

    /// A top-down grasp at height `z`: approach -z (world), closing along world x.
    fn top_down(x: f64, y: f64, z: f64) -> Isometry3<f64> {
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        Isometry3::from_parts(Translation3::new(x, y, z), rotation)
    }

    /// `points` (world frame) as one obstacle, framed by the identity.
    fn collides(
        grasp: &Isometry3<f64>,
        width: f64,
        hand: &HandConfig,
        table: &TablePlane,
        points: &[[f32; 3]],
    ) -> bool {
        let identity = Isometry3::identity();
        let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
        for p in points {
            let v = Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
            lo = lo.inf(&v);
            hi = hi.sup(&v);
        }
        let obstacle = Obstacle {
            world_from_object: &identity,
            extent_min_m: &lo,
            extent_max_m: &hi,
            points,
        };
        let obstacles = if points.is_empty() { vec![] } else { vec![obstacle] };
        hand_collides(
            grasp,
            width,
            &Gripper::default(),
            hand,
            table,
            &obstacles,
            Some(0),
        )
    }

    /// Points filling a box (world frame) on a 5 mm grid.
    fn block(lo: [f64; 3], hi: [f64; 3]) -> Vec<[f32; 3]> {
        let mut out = Vec::new();
        let steps = |a: f64, b: f64| ((b - a) / 0.005).round() as usize;
        for i in 0..=steps(lo[0], hi[0]) {
            for j in 0..=steps(lo[1], hi[1]) {
                for k in 0..=steps(lo[2], hi[2]) {
                    out.push([
                        (lo[0] + i as f64 * 0.005) as f32,
                        (lo[1] + j as f64 * 0.005) as f32,
                        (lo[2] + k as f64 * 0.005) as f32,
                    ]);
                }
            }
        }
        out
    }

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
        // A shelf over the grasp, 12 cm above the fingertips: only the swept
        // approach passes through it (pads and palm end 9 cm above them).
        let shelf = block([-0.05, -0.05, 0.16], [0.05, 0.05, 0.165]);
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

    /// Local points with their box, framed by `world_from_object`.
    type Framed = (Vec<[f32; 3]>, Vector3<f64>, Vector3<f64>);

    fn obstacle_of<'a>(world_from_object: &'a Isometry3<f64>, (local, lo, hi): &'a Framed) -> Obstacle<'a> {
        Obstacle {
            world_from_object,
            extent_min_m: lo,
            extent_max_m: hi,
            points: local,
        }
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
        let framed = |points: &[[f32; 3]]| -> Framed {
            (points.to_vec(), Vector3::repeat(-1.0), Vector3::repeat(1.0))
        };
        // A 4 cm box, grasped 2 cm below its top, 6 cm wide (the pads open
        // to 8 cm); a flat object lying across its top: between the pads,
        // clear of the pads and of the palm.
        let target = framed(&block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.06]));
        let on_top = framed(&block([-0.02, -0.01, 0.065], [0.02, 0.01, 0.075]));
        let grasp = top_down(0.0, 0.0, 0.04);
        let objects = [obstacle_of(&identity, &target), obstacle_of(&identity, &on_top)];
        let hit = |own| hand_collision(&grasp, 0.06, &gripper, &hand, &table, &objects, own);
        assert_eq!(hit(Some(0)), Some(Collision::Object(1)));
        // Seen as one object with the box, the hand closes on both: allowed.
        let merged = framed(&[target.0.clone(), on_top.0.clone()].concat());
        let collides = |objects: &[Obstacle<'_>], own| {
            hand_collides(&grasp, 0.06, &gripper, &hand, &table, objects, own)
        };
        let one = [obstacle_of(&identity, &merged)];
        assert!(!collides(&one, Some(0)));
        // Without a known own object, every object's points count there.
        assert!(collides(&one, None));
        // The flat object 5 cm aside, clear of the pads' paths: no collision.
        let aside = framed(&block([-0.02, 0.05, 0.065], [0.02, 0.07, 0.075]));
        assert!(!collides(
            &[obstacle_of(&identity, &target), obstacle_of(&identity, &aside)],
            Some(0)
        ));
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
        let framed =
            |points: Vec<[f32; 3]>| -> Framed { (points, Vector3::repeat(-1.0), Vector3::repeat(1.0)) };
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
        // A 4 x 4 cm box 10 cm tall, fingertips 3 cm below its top: the
        // palm (behind the 4 cm pads) is 1 cm over it, so the hand passes
        // 5 mm deeper.
        let own: Framed = (
            block([-0.02, -0.02, 0.0], [0.02, 0.02, 0.10]),
            Vector3::repeat(-1.0),
            Vector3::repeat(1.0),
        );
        let objects = [obstacle_of(&identity, &own)];
        let hit =
            |pose: &Isometry3<f64>| hand_collision(pose, 0.04, &gripper, &hand, &table, &objects, Some(0));
        let grasp = top_down(0.0, 0.0, 0.07);
        assert_eq!(hit(&grasp), None);
        let deeper =
            deepen(&grasp, 0.04, &gripper, &hand, &table, 0.003, |p| hit(p).is_none()).expect("deeper");
        assert!(
            (deeper.translation.z - (0.07 - hand.deepen_m)).abs() < 1e-12,
            "{deeper}"
        );
        assert!(deeper.rotation.angle_to(&grasp.rotation) < 1e-12);
        // Fingertips already 3.6 cm below the top: 5 mm more puts the palm
        // 1 mm into it, 2.5 mm leaves it 1.5 mm over.
        let grasp = top_down(0.0, 0.0, 0.064);
        let deeper =
            deepen(&grasp, 0.04, &gripper, &hand, &table, 0.003, |p| hit(p).is_none()).expect("half");
        assert!(
            (deeper.translation.z - (0.064 - hand.deepen_m / 2.0)).abs() < 1e-12,
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
