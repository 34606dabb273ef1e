//! One view's maps -> 6-DoF grasps (DESIGN.md, method step 6).
//!
//! For each quality peak `(u, v)`: the angle `phi = atan2(sin 2phi, cos 2phi) / 2`
//! is measured in the image from +u towards +v; the closing direction is
//! `cos(phi) u + sin(phi) v`; the approach is the view's viewing direction.
//! The fingertips are placed `insertion_m` past the nearest surface found
//! within `surface_radius_m` of the pixel (the paper's Delta = 5 mm), less if
//! the pads would otherwise come closer than `table_clearance_m` to the
//! table. A peak that gives no grasp is counted by cause ([`Decoded`]): its
//! predicted opening wider than the gripper's stroke (plus `wide_slack_m`),
//! or no pose (no seen surface near it, pads that cannot clear the table, a
//! width or angle that is not a number).
//!
//! Grasp frame (DESIGN.md): origin midway between the fingertips, +z the
//! approach, +x the closing direction, +y = z x x.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

use super::peaks::smoothed_peaks;
use crate::gripper::Gripper;
use crate::infer::{Channel, GraspMaps, ModelContract};
use crate::segment::TablePlane;
use crate::view::{OrthoView, ViewAxis};

/// Settings of the decoding stage.
#[derive(Debug, Clone, PartialEq)]
pub struct DecodeConfig {
    /// Gaussian smoothing of the quality map before peak search (px); 0 = off.
    pub smoothing_sigma_px: f32,
    /// Peaks closer than this to a better one are suppressed (px).
    pub nms_radius_px: usize,
    /// At most this many peaks per view.
    pub peaks_per_view: usize,
    /// Radius searched for the nearest surface around a peak (m).
    pub surface_radius_m: f32,
    /// How far the fingertips go past that surface (m). 3 cm of the 2F-140's
    /// 4 cm pads: in `sim eval` 1.5 cm slipped in 39 of 139 attempts, 3 cm in
    /// 12 of 130 (docs/experiments/); on the referee's train pool 4 cm was
    /// level (docs/experiments/2026-11-28-finger-length.md).
    pub insertion_m: f64,
    /// Smallest distance kept between a pad and the table (m).
    pub table_clearance_m: f64,
    /// Added to the predicted opening (within the stroke): the hand arrives
    /// this much wider and closes to contact. A network trained with MSE
    /// under-predicts openings (measured in BENCHMARKS.md / sim README).
    pub opening_margin_m: f64,
    /// Ranking: each grasp's quality less this much per 10 cm of its lever
    /// arm, the horizontal distance from the object's visible centre to the
    /// closing line ([`lever_arm_m`]): the planner cannot see mass, but the
    /// centre is its best guess, and a grip far from it lets a heavy end
    /// turn out of the pads. 0: by quality alone.
    pub centre_weight: f32,
    /// A peak whose predicted opening exceeds the gripper's stroke by up to
    /// this much (m) is decoded at the full stroke, and the hand check
    /// judges it against the object's seen points; a wider one is counted
    /// `too_wide`. 0: the network's width alone refuses it
    /// (docs/experiments/2026-11-30-wider-than-the-stroke.md).
    pub wide_slack_m: f64,
}

impl Default for DecodeConfig {
    fn default() -> Self {
        Self {
            smoothing_sigma_px: 1.0,
            nms_radius_px: 4,
            peaks_per_view: 3,
            surface_radius_m: 0.005,
            insertion_m: 0.03,
            table_clearance_m: 0.003,
            opening_margin_m: 0.02,
            centre_weight: 0.0,
            wide_slack_m: 0.03,
        }
    }
}

/// One view's candidate grasps, best first, and its peaks that gave none, by cause.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Decoded {
    /// The candidates.
    pub grasps: Vec<Grasp>,
    /// Peaks whose predicted opening exceeds the stroke by more than `wide_slack_m`.
    pub too_wide: usize,
    /// Peaks that give no pose: no seen surface within `surface_radius_m`,
    /// pads that cannot clear the table at any insertion, or a width or
    /// angle that is not a positive number.
    pub no_pose: usize,
}

/// How far gravity acting at `centre` pulls about the grasp's closing line
/// (m): the distance between them across the pads, in the horizontal plane.
/// 0 for a closing line that stands vertical.
pub fn lever_arm_m(grasp: &Grasp, centre: &Vector3<f64>) -> f64 {
    let closing = grasp.world_from_grasp.rotation * Vector3::x();
    let across = closing.cross(&Vector3::z());
    let norm = across.norm();
    if norm < 1e-9 {
        return 0.0;
    }
    ((centre - grasp.world_from_grasp.translation.vector).dot(&across) / norm).abs()
}

/// What the planner changed about a grasp after decoding it from its
/// pixel, or why it ranked the grasp late: each step of the hand check
/// that acted on it ([`HandConfig`]). All false: the grasp as decoded.
///
/// [`HandConfig`]: crate::decode::HandConfig
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Repairs {
    /// The pads would have met the object's own seen points: opened to
    /// what was seen of it, and re-checked.
    pub refit: bool,
    /// The hand would have hit a neighbour, or its own object at every
    /// opening: turned about the approach until it passed (ranked after the
    /// grasps that passed as planned).
    pub turned_away: bool,
    /// Turned about the approach to square the pads to the surfaces they
    /// meet, as seen.
    pub squared: bool,
    /// Moved deeper along the approach, where the hand and the table allow.
    pub deepened: bool,
    /// A pad reaches past its view's border, maybe onto a part of the
    /// object never seen (ranked last).
    pub out_of_view: bool,
}

impl Repairs {
    /// Every step's name, in the order [`Repairs::names`] gives them.
    pub const ALL_NAMES: [&'static str; 5] = ["refit", "turned away", "squared", "deepened", "out of view"];

    /// The steps that acted, by name ([`Repairs::ALL_NAMES`]), in that
    /// order; empty for none.
    pub fn names(self) -> Vec<&'static str> {
        [
            self.refit,
            self.turned_away,
            self.squared,
            self.deepened,
            self.out_of_view,
        ]
        .into_iter()
        .zip(Self::ALL_NAMES)
        .filter_map(|(on, name)| on.then_some(name))
        .collect()
    }
}

/// A 6-DoF parallel-jaw grasp in the world.
#[derive(Debug, Clone, PartialEq)]
pub struct Grasp {
    /// Pose of the grasp frame in the world.
    pub world_from_grasp: Isometry3<f64>,
    /// Opening between the pads (m).
    pub width_m: f64,
    /// Predicted quality in [0, 1].
    pub quality: f32,
    /// The object it grasps.
    pub object_id: u32,
    /// The view it was found in.
    pub view: ViewAxis,
    /// Peak pixel `[u, v]` in that view.
    pub pixel: [u32; 2],
    /// Image angle phi (rad), in [-pi/2, pi/2], as the network gave it at
    /// the peak; the pose's closing direction may be turned from it about
    /// the approach by up to [`HandConfig::square_turn_deg`] (the planner's
    /// squaring).
    ///
    /// [`HandConfig::square_turn_deg`]: crate::decode::HandConfig::square_turn_deg
    pub angle_rad: f32,
    /// What the planner's hand check changed about it after decoding.
    pub repairs: Repairs,
}

/// A rendered view and where its object sits in the world.
#[derive(Debug, Clone, Copy)]
pub struct ViewPlacement<'a> {
    /// The view.
    pub view: &'a OrthoView,
    /// Object frame of the view's object.
    pub world_from_object: &'a Isometry3<f64>,
    /// Id of the object.
    pub object_id: u32,
}

/// Grasps of one view from view `index` of `maps`, best first, and what its
/// other peaks were lost to.
#[allow(clippy::too_many_arguments)]
pub fn decode_view(
    placement: &ViewPlacement<'_>,
    maps: &GraspMaps,
    index: usize,
    contract: &ModelContract,
    gripper: &Gripper,
    table: &TablePlane,
    min_quality: f32,
    config: &DecodeConfig,
) -> Decoded {
    let view = placement.view;
    let l = view.size_px;
    let channel = |c: Channel| maps.channel(index, contract.channel_index(c));
    let (cos2, sin2, width) = (
        channel(Channel::Cos2Phi),
        channel(Channel::Sin2Phi),
        channel(Channel::Width),
    );
    let mut out = Decoded::default();
    let peaks = smoothed_peaks(
        channel(Channel::Quality),
        l,
        config.smoothing_sigma_px,
        min_quality,
        config.nms_radius_px,
        config.peaks_per_view,
    );
    for (u, v, q) in peaks {
        let i = v * l + u;
        let (c, s) = (cos2[i], sin2[i]);
        let predicted_m = f64::from(width[i]) * f64::from(contract.width_scale_m);
        if !(c.is_finite() && s.is_finite() && predicted_m.is_finite()) || predicted_m <= 0.0 {
            out.no_pose += 1;
            continue;
        }
        if predicted_m > gripper.max_width_m + config.wide_slack_m {
            out.too_wide += 1;
            continue;
        }
        let width_m = (predicted_m + config.opening_margin_m).min(gripper.max_width_m);
        let phi = 0.5 * f64::from(s).atan2(f64::from(c));
        let Some(world_from_grasp) = grasp_at(placement, u, v, phi, width_m, gripper, table, config) else {
            out.no_pose += 1;
            continue;
        };
        out.grasps.push(Grasp {
            world_from_grasp,
            width_m,
            quality: q,
            object_id: placement.object_id,
            view: view.axis,
            pixel: [u as u32, v as u32],
            angle_rad: phi as f32,
            repairs: Repairs::default(),
        });
    }
    out
}

/// The 6-DoF grasp that view pixel `(u, v)`, image angle `phi_rad` and
/// opening `width_m` stand for, as the planner decodes it: the nearest
/// surface within `config.surface_radius_m` of the pixel, the view's viewing
/// direction as the approach, fingertips inserted past the surface as far as
/// the table allows. `None` when no surface is near the pixel or the pads
/// cannot clear the table. The simulator labels candidates through this
/// same function, so training targets and serving agree.
#[allow(clippy::too_many_arguments)]
pub fn grasp_at(
    placement: &ViewPlacement<'_>,
    u: usize,
    v: usize,
    phi_rad: f64,
    width_m: f64,
    gripper: &Gripper,
    table: &TablePlane,
    config: &DecodeConfig,
) -> Option<Isometry3<f64>> {
    let view = placement.view;
    let world_from_object = placement.world_from_object;
    let world_from_view = world_from_object.rotation.to_rotation_matrix().matrix() * view.object_from_view;
    let approach = world_from_view.column(2).into_owned();
    let surface_z = view.nearest_depth_within(u, v, config.surface_radius_m)?;
    let closing = (world_from_view * Vector3::new(phi_rad.cos(), phi_rad.sin(), 0.0)).normalize();
    let surface = world_from_object
        * nalgebra::Point3::from(view.point_in_object(u as f64 + 0.5, v as f64 + 0.5, f64::from(surface_z)));
    let insertion = clear_of_table(
        &surface.coords,
        &closing,
        &approach,
        width_m,
        gripper,
        table,
        config,
    )?;
    let origin = surface.coords + insertion * approach;
    let rotation = Matrix3::from_columns(&[closing, approach.cross(&closing), approach]);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rotation));
    // Renormalise: the product of two rotations drifts from unit norm at 1e-16.
    let rotation = UnitQuaternion::new_normalize(rotation.into_inner());
    Some(Isometry3::from_parts(Translation3::from(origin), rotation))
}

/// How far the lowest pad corner lies above the table relative to the
/// fingertip midpoint (m; negative: below it), for a hand closing along
/// `closing` and approaching along `approach` (unit vectors) at opening
/// `width_m`.
pub(crate) fn lowest_pad_corner(
    closing: &Vector3<f64>,
    approach: &Vector3<f64>,
    width_m: f64,
    gripper: &Gripper,
    table: &TablePlane,
) -> f64 {
    let n = &table.normal;
    let across = approach.cross(closing);
    -(0.5 * width_m * n.dot(closing).abs()) - 0.5 * gripper.finger_width_m * n.dot(&across).abs()
        + (-gripper.finger_depth_m * n.dot(approach)).min(0.0)
}

/// The insertion (<= `config.insertion_m`) that keeps every pad corner at
/// least `table_clearance_m` above the table, or `None` if none does.
fn clear_of_table(
    surface: &Vector3<f64>,
    closing: &Vector3<f64>,
    approach: &Vector3<f64>,
    width_m: f64,
    gripper: &Gripper,
    table: &TablePlane,
    config: &DecodeConfig,
) -> Option<f64> {
    let n = &table.normal;
    let margin = table.height_of(surface) + lowest_pad_corner(closing, approach, width_m, gripper, table)
        - config.table_clearance_m;
    let descent = -n.dot(approach); // height lost per metre of insertion
    if descent > 1e-9 {
        let limit = margin / descent;
        (limit >= 0.0).then_some(config.insertion_m.min(limit))
    } else {
        (margin + config.insertion_m * -descent >= 0.0).then_some(config.insertion_m)
    }
}

#[cfg(test)]
mod tests {
    use super::Repairs;

    #[test]
    fn repairs_name_the_steps_that_acted_in_order() {
        assert!(Repairs::default().names().is_empty());
        let every = Repairs {
            refit: true,
            turned_away: true,
            squared: true,
            deepened: true,
            out_of_view: true,
        };
        assert_eq!(every.names(), Repairs::ALL_NAMES);
        let two = Repairs {
            squared: true,
            out_of_view: true,
            ..Repairs::default()
        };
        assert_eq!(two.names(), ["squared", "out of view"]);
    }

    #[test]
    fn the_lever_arm_is_the_horizontal_distance_across_the_pads() {
        use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

        // From above (approach -z), closing along world x, at (0.1, 0.2, 0.05).
        let down = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        let grasp = super::Grasp {
            world_from_grasp: Isometry3::from_parts(Translation3::new(0.1, 0.2, 0.05), down),
            width_m: 0.06,
            quality: 0.9,
            object_id: 0,
            view: crate::view::ViewAxis::Top,
            pixel: [0, 0],
            angle_rad: 0.0,
            repairs: Repairs::default(),
        };
        let arm = |dx: f64, dy: f64, dz: f64| {
            super::lever_arm_m(&grasp, &Vector3::new(0.1 + dx, 0.2 + dy, 0.05 + dz))
        };
        assert!((arm(0.0, 0.03, 0.0) - 0.03).abs() < 1e-12);
        assert!((arm(0.0, -0.03, 0.0) - 0.03).abs() < 1e-12);
        // Along the closing line or straight below it: no lever.
        assert!(arm(0.04, 0.0, 0.0).abs() < 1e-12);
        assert!(arm(0.0, 0.0, -0.08).abs() < 1e-12);
        // A closing line standing vertical: none either.
        let vertical = super::Grasp {
            world_from_grasp: Isometry3::from_parts(
                Translation3::new(0.1, 0.2, 0.05),
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2),
            ),
            ..grasp
        };
        assert_eq!(super::lever_arm_m(&vertical, &Vector3::new(0.3, 0.3, 0.0)), 0.0);
    }
}
