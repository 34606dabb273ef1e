//! Analytic grasp labels: one 6-DoF parallel-jaw grasp against a scene,
//! with a parametric gripper (default Robotiq 2F-140).
//!
//! The grasp frame is DESIGN.md's: origin midway between the fingertips, +z
//! the approach (into the object), +x the closing direction. The pads span
//! `z` in `[-pad_depth, 0]`; the palm sits behind them. A grasp is checked
//! the way the gripper would meet it:
//!
//! 1. **Open**: pads opened to `width + clearance` (at most the stroke) and
//!    the palm must touch nothing: not the object, not a neighbour, not the
//!    table. When the pads at full stroke still cut the object, it is too
//!    wide.
//! 2. **Close**: a 5 x 5 grid of rays from each pad's inner face, along the
//!    closing direction, finds the first surface each pad meets. A pad that
//!    meets a neighbour before the object collides; pads that meet nothing
//!    miss.
//! 3. **Antipodal**: the contact normals of both pads must lie inside the
//!    friction cone (`atan(mu)`) around the closing direction. A pad's
//!    contact normal is the surface normal where its first ray lands, or,
//!    with `pad_compliance_m` above 0, the mean normal of every ray that
//!    lands within that distance of it (a rubber pad pressed in that far).
//! 4. **Torque**: the object's weight about the closing line (its mass times
//!    g times how far its centre of mass sits from that line, sideways) must
//!    stay under what the pads' friction resists; two pads squeezing a
//!    rigid body hold it against a pull but only weakly against a turn.
//!
//! The cone (20 degrees) and the torque limit (0.6 N m; data version
//! sim-6) are calibrated so that positives hold in the physics trial that
//! `sim eval` runs (`studies/torque_slip.rs`): a wider cone and no torque
//! term labelled grasps that slipped. The measurements:
//! docs/experiments/2026-11-24-sim5-torque-labels.md and
//! 2026-11-24-sim6-torque-recheck.md; a pad that gives (the mean normal
//! over a few millimetres, tried on 2026-11-27 and removed: no model used
//! it): 2026-11-27-pad-that-gives.md.
//!
//! The score (for positives) combines the paper's terms: the share of pad
//! rays that meet the object (how much of the object is between the
//! fingers) and how well the contact normals agree with the closing
//! direction; and how little the weight turns the object in the grip. The
//! paper's distance to the view centre belongs to the view and is added
//! where views are labelled.

use nalgebra::Isometry3;
use parry3d::math::{Pose, Rotation, Vector};
use parry3d::query::{Ray, intersection_test};
use parry3d::shape::{Cuboid, Shape};

use crate::scene::Scene;

/// A parallel-jaw gripper, as the labels see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperModel {
    /// Largest opening (m).
    pub max_width_m: f32,
    /// Pad extent across the closing direction (m).
    pub pad_width_m: f32,
    /// Pad extent along the approach (m).
    pub pad_depth_m: f32,
    /// Pad thickness along the closing direction (m).
    pub pad_thickness_m: f32,
    /// Palm (the gripper body behind the pads): depth along the approach (m).
    pub palm_depth_m: f32,
    /// Palm extent across the closing direction (m).
    pub palm_width_m: f32,
    /// Opening beyond the grasp width before closing (m).
    pub clearance_m: f32,
    /// Friction coefficient the labels assume: contact normals must lie
    /// within `atan(friction)` of the closing direction. Not the physics'
    /// coefficient (0.8): calibrated so that positives hold there (module
    /// documentation).
    pub friction: f32,
    /// Largest torque of the object's weight about the closing line that
    /// the grip takes (N m); calibrated likewise.
    pub max_torque_nm: f32,
}

impl GripperModel {
    /// Robotiq 2F-140: 0-140 mm stroke, pads 27 mm wide and about 40 mm deep
    /// (datasheet), body about 75 mm wide; a 20 degree friction cone and
    /// 0.6 N m of torque (data version sim-6; sim-5 had 0.15 N m).
    pub fn robotiq_2f_140() -> Self {
        Self {
            max_width_m: 0.14,
            pad_width_m: 0.027,
            pad_depth_m: 0.04,
            pad_thickness_m: 0.01,
            palm_depth_m: 0.05,
            palm_width_m: 0.075,
            clearance_m: 0.02,
            friction: 0.364, // tan(20 degrees)
            max_torque_nm: 0.6,
        }
    }

    /// The planner's view of this gripper: stroke, pad width and depth.
    pub fn planner_gripper(&self) -> mvgrasp_core::Gripper {
        mvgrasp_core::Gripper {
            max_width_m: f64::from(self.max_width_m),
            finger_width_m: f64::from(self.pad_width_m),
            finger_depth_m: f64::from(self.pad_depth_m),
        }
    }
}

/// What a grasp comes to.
#[derive(Debug, Clone, PartialEq)]
pub enum GraspLabel {
    /// It holds, analytically.
    Positive {
        /// In [0, 1].
        score: f32,
        /// Opening between the contacts (m).
        contact_width_m: f32,
    },
    /// The object is wider than the stroke where the pads are.
    TooWide,
    /// A pad or the palm hits something before closing, or a pad meets a
    /// neighbour first while closing.
    Collision {
        /// What was hit.
        obstacle: Obstacle,
        /// By which part of the hand.
        part: HandPart,
    },
    /// The pads close on nothing of the object.
    Missed,
    /// A contact normal lies outside the friction cone (e.g. an edge or corner).
    NotAntipodal {
        /// The larger angle between a contact normal and the closing direction (deg).
        worst_angle_deg: f32,
    },
    /// Antipodal, but the object's weight would turn it in the grip: its
    /// centre of mass sits too far to the side of the closing line.
    Twists {
        /// The weight's torque about the closing line (N m).
        torque_nm: f32,
    },
}

/// What a hand collided with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Obstacle {
    /// The table top.
    Table,
    /// The object being grasped.
    Target,
    /// Another object (its index in the scene).
    Neighbour(usize),
}

/// The part of the hand that collided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum HandPart {
    /// The pad on the -x side.
    LeftPad,
    /// The pad on the +x side.
    RightPad,
    /// The gripper body behind the pads.
    Palm,
    /// A pad while closing (it met a neighbour before the object).
    Closing,
}

impl HandPart {
    /// Report name.
    pub fn name(self) -> &'static str {
        match self {
            Self::LeftPad => "left pad",
            Self::RightPad => "right pad",
            Self::Palm => "palm",
            Self::Closing => "closing",
        }
    }
}

impl GraspLabel {
    /// True for [`GraspLabel::Positive`].
    pub fn is_positive(&self) -> bool {
        matches!(self, Self::Positive { .. })
    }

    /// Report name of the label's kind.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Positive { .. } => "positive",
            Self::TooWide => "too wide",
            Self::Collision { .. } => "collision",
            Self::Missed => "missed",
            Self::NotAntipodal { .. } => "not antipodal",
            Self::Twists { .. } => "twists",
        }
    }

    /// The label's kind, finer than [`GraspLabel::name`] where the hand
    /// collides: what it hit and with which part (the two pads are one).
    /// The keys of `sim datagen`'s per-view refusal counts.
    pub fn reason(&self) -> &'static str {
        let Self::Collision { obstacle, part } = self else {
            return self.name();
        };
        match (obstacle, part) {
            (Obstacle::Table, HandPart::Palm) => "table: palm",
            (Obstacle::Table, _) => "table: pad",
            (Obstacle::Target, HandPart::Palm) => "object: palm",
            (Obstacle::Target, _) => "object: pad",
            (Obstacle::Neighbour(_), HandPart::Palm) => "neighbour: palm",
            (Obstacle::Neighbour(_), HandPart::Closing) => "neighbour: closing",
            (Obstacle::Neighbour(_), _) => "neighbour: pad",
        }
    }
}

/// `iso` as parry's single-precision pose.
pub fn pose_of(iso: &Isometry3<f64>) -> Pose {
    let t = iso.translation.vector;
    let q = iso.rotation.quaternion();
    Pose::from_parts(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        Rotation::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32).normalize(),
    )
}

/// Rays per pad side.
const GRID: usize = 5;

/// Labels the grasp `world_from_grasp` of opening `width_m` on object
/// `target` of `scene`.
pub fn label_grasp(
    scene: &Scene,
    target: usize,
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &GripperModel,
) -> GraspLabel {
    let g = gripper;
    let grasp = pose_of(world_from_grasp);
    let width = width_m as f32;
    let opening = (width + g.clearance_m).min(g.max_width_m);
    let half_pad = Vector::new(g.pad_thickness_m / 2.0, g.pad_width_m / 2.0, g.pad_depth_m / 2.0);
    let pad = Cuboid::new(half_pad);
    let pad_at = |side: f32| {
        grasp
            * Pose::from_translation(Vector::new(
                side * (opening / 2.0 + g.pad_thickness_m / 2.0),
                0.0,
                -g.pad_depth_m / 2.0,
            ))
    };
    let palm = Cuboid::new(Vector::new(
        opening / 2.0 + g.pad_thickness_m,
        g.palm_width_m / 2.0,
        g.palm_depth_m / 2.0,
    ));
    let palm_pose =
        grasp * Pose::from_translation(Vector::new(0.0, 0.0, -g.pad_depth_m - g.palm_depth_m / 2.0));
    // The table as a thick slab under its top.
    let table = Cuboid::new(Vector::new(scene.table_half[0], scene.table_half[1], 0.5));
    let table_pose = Pose::from_translation(Vector::new(0.0, 0.0, scene.table_z - 0.5));
    let hits = |pose: &Pose, shape: &dyn Shape, other_pose: &Pose, other: &dyn Shape| {
        intersection_test(pose, shape, other_pose, other).is_ok_and(|i| i.intersecting)
    };

    // 1. Open.
    for (name, part_pose, part) in [
        (HandPart::LeftPad, pad_at(-1.0), pad),
        (HandPart::RightPad, pad_at(1.0), pad),
        (HandPart::Palm, palm_pose, palm),
    ] {
        if hits(&part_pose, &part, &table_pose, &table) {
            return GraspLabel::Collision {
                obstacle: Obstacle::Table,
                part: name,
            };
        }
        for (i, o) in scene.objects.iter().enumerate() {
            if hits(&part_pose, &part, &o.world_from_object, o.model.shape.as_ref()) {
                if i == target && name != HandPart::Palm && opening >= g.max_width_m {
                    return GraspLabel::TooWide;
                }
                return GraspLabel::Collision {
                    obstacle: if i == target {
                        Obstacle::Target
                    } else {
                        Obstacle::Neighbour(i)
                    },
                    part: name,
                };
            }
        }
    }

    // 2. Close: rays from each pad's inner face along the closing direction.
    let closing = grasp.rotation * Vector::X;
    // Every ray of each pad that meets the object: (distance, normal).
    let mut pad_hits = [[(f32::INFINITY, Vector::ZERO); GRID * GRID]; 2];
    let mut object_hits = 0usize;
    for (k, side) in [-1.0f32, 1.0].into_iter().enumerate() {
        let dir = closing * -side; // the left pad (-x) closes towards +x
        for a in 0..GRID {
            for b in 0..GRID {
                let y = (a as f32 / (GRID - 1) as f32 - 0.5) * g.pad_width_m * 0.9;
                let z = -(b as f32 / (GRID - 1) as f32) * g.pad_depth_m * 0.95 - 0.001;
                let origin = grasp * Vector::new(side * opening / 2.0, y, z);
                let ray = Ray::new(origin, dir);
                let mut nearest = (opening, None::<usize>, Vector::ZERO);
                for (i, o) in scene.objects.iter().enumerate() {
                    let hit =
                        o.model
                            .shape
                            .cast_ray_and_get_normal(&o.world_from_object, &ray, nearest.0, true);
                    if let Some(hit) = hit.filter(|h| h.time_of_impact < nearest.0) {
                        nearest = (hit.time_of_impact, Some(i), hit.normal);
                    }
                }
                match nearest.1 {
                    Some(i) if i == target => {
                        object_hits += 1;
                        pad_hits[k][a * GRID + b] = (nearest.0, nearest.2);
                    }
                    Some(i) => {
                        return GraspLabel::Collision {
                            obstacle: Obstacle::Neighbour(i),
                            part: HandPart::Closing,
                        };
                    }
                    None => {}
                }
            }
        }
    }
    // Each pad's first contact: its nearest ray (the first of equals, in grid order).
    let contact = pad_hits.map(|rays| {
        rays.into_iter()
            .fold((f32::INFINITY, Vector::ZERO), |first, ray| {
                if ray.0 < first.0 { ray } else { first }
            })
    });
    if contact.iter().any(|(t, _)| !t.is_finite()) {
        return GraspLabel::Missed;
    }
    let contact_width = opening - contact[0].0 - contact[1].0;

    // 3. Antipodal: each normal opposes its pad's closing motion within the cone.
    let cone = g.friction.atan();
    let mut worst = 0.0f32;
    for (k, side) in [-1.0f32, 1.0].into_iter().enumerate() {
        let towards_pad = closing * side; // a surface facing the pad at +-x
        let angle = contact[k].1.normalize().dot(towards_pad).clamp(-1.0, 1.0).acos();
        worst = worst.max(angle);
    }
    if worst > cone {
        return GraspLabel::NotAntipodal {
            worst_angle_deg: worst.to_degrees(),
        };
    }

    // 4. Torque of the weight about the closing line through the grasp centre.
    let torque = weight_torque_nm(&scene.objects[target], &grasp);
    if torque > g.max_torque_nm {
        return GraspLabel::Twists { torque_nm: torque };
    }
    let coverage = object_hits as f32 / (2 * GRID * GRID) as f32;
    let alignment = 1.0 - worst / cone;
    let steadiness = 1.0 - torque / g.max_torque_nm;
    GraspLabel::Positive {
        score: (0.4 * coverage + 0.4 * alignment + 0.2 * steadiness).clamp(0.0, 1.0),
        contact_width_m: contact_width,
    }
}

/// A top-down grasp over `object`: closing horizontally at `yaw` (rad from
/// +x), the grasp origin (the fingertips) `depth_m` below the object's top
/// over the centre of its box, moved `sideways_m` along the jaws' width
/// (grasp +y). The samples that calibrate the labels against physics use it.
pub fn top_down_over(
    object: &crate::scene::PlacedObject,
    yaw: f64,
    depth_m: f64,
    sideways_m: f64,
) -> Isometry3<f64> {
    use nalgebra::{Rotation3, Translation3, UnitQuaternion, Vector3};

    let (lo, hi) = (object.world_aabb.mins, object.world_aabb.maxs);
    let closing = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
    let approach = -Vector3::z();
    let across = approach.cross(&closing);
    let centre = Vector3::new(
        f64::from(lo.x + hi.x) / 2.0,
        f64::from(lo.y + hi.y) / 2.0,
        f64::from(hi.z) - depth_m,
    ) + across * sideways_m;
    Isometry3::from_parts(
        Translation3::from(centre),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_basis_unchecked(&[closing, across, approach])),
    )
}

/// Standard gravity (m/s^2).
const G: f32 = 9.81;

/// The torque (N m, magnitude) of `object`'s weight about the closing line
/// (grasp `x` through the grasp origin).
pub fn weight_torque_nm(object: &crate::scene::PlacedObject, grasp: &Pose) -> f32 {
    let com = object.world_from_object * object.model.local_com;
    let closing = grasp.rotation * Vector::X;
    let weight = Vector::new(0.0, 0.0, -object.model.mass_kg * G);
    (com - grasp.translation).cross(weight).dot(closing).abs()
}
