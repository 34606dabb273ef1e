//! Physics confirmation of a grasp in rapier3d: close, lift 15 cm, shake,
//! and see whether the object is still held.
//!
//! The gripper is the design `../shared/notes/rapier-grasping.md` found to
//! work: a kinematic palm and two kinematic pads that close until each
//! measures the squeeze force, then a slow force servo keeps 50-200 N while
//! the hand lifts and shakes. Contacts are stiffened (300 Hz, damping ratio
//! 10), contact recycling is off, 240 Hz steps with 4 solver iterations.
//! Objects are their convex compounds at the model's mass; the table is
//! fixed. The servo's force comes from penetration, not from a motor: this
//! judges geometry and friction, not force limits. Every hand motion
//! starts and ends at rest and speeds up and slows down at a robot's pace
//! (1 m/s^2): a kinematic hand that jumps to speed in one 1/240 s step
//! shakes objects loose that a real arm would carry
//! (docs/experiments/2026-11-24-sim-eval-loop.md).

use nalgebra::Isometry3;
use rapier3d::prelude::{
    ColliderBuilder, ColliderHandle, PhysicsWorld, Pose, RigidBodyBuilder, RigidBodyHandle, SharedShape,
    Vector,
};

use crate::grasp::{GripperModel, pose_of};
use crate::scene::{PlacedObject, Scene};

/// How a trial runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialConfig {
    /// Step (s).
    pub dt: f32,
    /// Friction of pads, objects and table.
    pub friction: f32,
    /// Pads stop closing at this force (N).
    pub squeeze_n: f32,
    /// The servo keeps the force in this band (N).
    pub hold_band_n: (f32, f32),
    /// Closing speed before contact (m/s).
    pub close_speed: f32,
    /// Servo speed (m/s).
    pub servo_speed: f32,
    /// Lift (m) and its speed (m/s).
    pub lift_m: f32,
    /// See `lift_m`.
    pub lift_speed: f32,
    /// The lift speeds up and slows down at this (m/s^2).
    pub lift_accel: f32,
    /// Shake amplitude (m) and frequency (Hz), across the closing direction,
    /// for `shake_s`: `shake_m (1 - cos)`, from rest and back, 2 x `shake_m`
    /// peak to peak.
    pub shake_m: f32,
    /// See `shake_m`.
    pub shake_hz: f32,
    /// See `shake_m`.
    pub shake_s: f32,
    /// After the shake, carry the object to a basket and let it go there;
    /// `None`: the trial ends with the shake.
    pub carry: Option<Basket>,
}

/// The basket of a carry: a box open at the top beside the table, its
/// floor at the table's height.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Basket {
    /// Centre of its floor in x and y (m); z is the table's.
    pub centre_xy: [f32; 2],
    /// Half the inner side (m).
    pub inner_half_m: f32,
    /// Wall height (m).
    pub wall_m: f32,
    /// Carry speed (m/s).
    pub speed: f32,
    /// Carry acceleration and deceleration (m/s^2), each leg from rest to
    /// rest.
    pub accel: f32,
    /// How long the object may fall and settle after the release (s).
    pub release_s: f32,
}

impl Default for Basket {
    fn default() -> Self {
        Self {
            centre_xy: [0.0, -0.75],
            inner_half_m: 0.15,
            wall_m: 0.12,
            speed: 0.5,
            accel: 1.0,
            release_s: 1.0,
        }
    }
}

impl Default for TrialConfig {
    fn default() -> Self {
        Self {
            dt: 1.0 / 240.0,
            friction: 0.8,
            squeeze_n: 100.0,
            hold_band_n: (50.0, 200.0),
            close_speed: 0.05,
            servo_speed: 0.005,
            lift_m: 0.15,
            lift_speed: 0.1,
            lift_accel: 1.0,
            shake_m: 0.01,
            shake_hz: 2.0,
            shake_s: 0.5,
            carry: None,
        }
    }
}

/// What a trial came to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TrialOutcome {
    /// Still between the pads after the lift and the shake (with a carry:
    /// and then let go into the basket, where it came to rest).
    Held {
        /// How far the object rose (m).
        lifted_m: f32,
    },
    /// The pads closed on each other, or never both reached the squeeze force.
    NoGrip,
    /// Gripped, then lost during the lift, the shake or the carry (or let
    /// go over the basket and came to rest outside it).
    Dropped {
        /// How far the object rose before it was lost (m).
        lifted_m: f32,
    },
}

impl TrialOutcome {
    /// True for [`TrialOutcome::Held`].
    pub fn is_held(&self) -> bool {
        matches!(self, Self::Held { .. })
    }
}

/// A physics world holding `scene`: gravity, the fixed table and every
/// object as a dynamic body at its pose and mass (their handles, in scene
/// order). Stepped at `dt` with the stiff, non-recycled contacts above.
pub(crate) fn scene_world(scene: &Scene, dt: f32, friction: f32) -> (PhysicsWorld, Vec<RigidBodyHandle>) {
    let mut world = PhysicsWorld::new();
    world.gravity = Vector::new(0.0, 0.0, -9.81);
    let p = &mut world.integration_parameters;
    p.dt = dt;
    p.num_solver_iterations = 4;
    p.length_unit = 0.1;
    p.contact_recycling = false;
    p.contact_softness.natural_frequency = 300.0;
    p.contact_softness.damping_ratio = 10.0;

    world.insert(
        RigidBodyBuilder::fixed().translation(Vector::new(0.0, 0.0, scene.table_z - 0.05)),
        ColliderBuilder::cuboid(scene.table_half[0], scene.table_half[1], 0.05).friction(friction),
    );
    let bodies = scene
        .objects
        .iter()
        .map(|o| add_object(&mut world, o, friction))
        .collect();
    (world, bodies)
}

/// Adds `object` to `world` as a dynamic body at its pose and mass.
pub(crate) fn add_object(world: &mut PhysicsWorld, object: &PlacedObject, friction: f32) -> RigidBodyHandle {
    world
        .insert(
            RigidBodyBuilder::dynamic().pose(object.world_from_object),
            ColliderBuilder::new(object.model.shape.clone())
                .mass(object.model.mass_kg)
                .friction(friction),
        )
        .0
}

/// One step of the grip servo while holding.
type Servo<'a> = dyn Fn(&PhysicsWorld, &mut Hand) + 'a;

/// Moves the hand (palm and pads) to a grasp pose for the next step.
type Place<'a> = dyn Fn(&mut PhysicsWorld, &Hand, &Pose) + 'a;

struct Hand {
    palm: RigidBodyHandle,
    pads: [RigidBodyHandle; 2],
    pad_colliders: [ColliderHandle; 2],
    /// Pad centre offsets along the closing axis (m, grasp frame).
    offsets: [f32; 2],
}

/// A trial's outcome and where every scene object ended up.
#[derive(Debug, Clone)]
pub struct Trial {
    /// What it came to.
    pub outcome: TrialOutcome,
    /// Final pose of every scene object, in scene order (the target too:
    /// in the hand, in the basket, or wherever it fell).
    pub poses: Vec<Pose>,
}

/// Runs the grasp `world_from_grasp` (opening `width_m`) on object `target`.
pub fn trial(
    scene: &Scene,
    target: usize,
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &GripperModel,
    config: &TrialConfig,
) -> TrialOutcome {
    run_trial(scene, target, world_from_grasp, width_m, gripper, config).outcome
}

/// [`trial`], also returning where the objects ended up, so a caller can
/// carry the disturbance over to the next attempt.
pub fn run_trial(
    scene: &Scene,
    target: usize,
    world_from_grasp: &Isometry3<f64>,
    width_m: f64,
    gripper: &GripperModel,
    config: &TrialConfig,
) -> Trial {
    let (mut world, bodies) = scene_world(scene, config.dt, config.friction);
    let poses = |world: &PhysicsWorld| bodies.iter().map(|&b| *world.bodies[b].position()).collect();
    let Some(&object) = bodies.get(target) else {
        return Trial {
            outcome: TrialOutcome::NoGrip,
            poses: poses(&world),
        };
    };
    if let Some(b) = &config.carry {
        let (h, t, inner) = (b.wall_m / 2.0, 0.005, b.inner_half_m);
        let [x, y] = b.centre_xy;
        let body = world.insert_body(RigidBodyBuilder::fixed().translation(Vector::new(x, y, scene.table_z)));
        for (hx, hy, hz, at) in [
            (inner + 2.0 * t, inner + 2.0 * t, t, Vector::new(0.0, 0.0, -t)),
            (t, inner + 2.0 * t, h, Vector::new(inner + t, 0.0, h)),
            (t, inner + 2.0 * t, h, Vector::new(-inner - t, 0.0, h)),
            (inner, t, h, Vector::new(0.0, inner + t, h)),
            (inner, t, h, Vector::new(0.0, -inner - t, h)),
        ] {
            let wall = ColliderBuilder::cuboid(hx, hy, hz)
                .translation(at)
                .friction(config.friction);
            world.insert_collider(wall, Some(body));
        }
    }
    let basket = config.carry;
    let start_z = world.bodies[object].translation().z;

    let grasp = pose_of(world_from_grasp);
    let g = gripper;
    let opening = ((width_m as f32) + g.clearance_m).min(g.max_width_m);
    let half = opening / 2.0 + g.pad_thickness_m / 2.0;
    let pad_pose = |grasp: &Pose, offset: f32| {
        *grasp * Pose::from_translation(Vector::new(offset, 0.0, -g.pad_depth_m / 2.0))
    };
    let palm_pose = |grasp: &Pose| {
        *grasp * Pose::from_translation(Vector::new(0.0, 0.0, -g.pad_depth_m - g.palm_depth_m / 2.0))
    };
    let (palm, _) = world.insert(
        RigidBodyBuilder::kinematic_position_based().pose(palm_pose(&grasp)),
        ColliderBuilder::new(SharedShape::cuboid(
            half + g.pad_thickness_m / 2.0,
            g.palm_width_m / 2.0,
            g.palm_depth_m / 2.0,
        ))
        .friction(config.friction),
    );
    let mut pads = Vec::new();
    for offset in [-half, half] {
        let (body, collider) = world.insert(
            RigidBodyBuilder::kinematic_position_based().pose(pad_pose(&grasp, offset)),
            ColliderBuilder::cuboid(g.pad_thickness_m / 2.0, g.pad_width_m / 2.0, g.pad_depth_m / 2.0)
                .friction(config.friction),
        );
        pads.push((body, collider));
    }
    let mut hand = Hand {
        palm,
        pads: [pads[0].0, pads[1].0],
        pad_colliders: [pads[0].1, pads[1].1],
        offsets: [-half, half],
    };
    let object_collider = world.bodies[object].colliders()[0];

    let force = |world: &PhysicsWorld, pad: ColliderHandle| -> f32 {
        world
            .contact_pair(pad, object_collider)
            .map_or(0.0, |pair| pair.total_impulse_magnitude() / config.dt)
    };
    let place = |world: &mut PhysicsWorld, hand: &Hand, grasp: &Pose| {
        world.bodies[hand.palm].set_next_kinematic_position(palm_pose(grasp));
        for k in 0..2 {
            world.bodies[hand.pads[k]].set_next_kinematic_position(pad_pose(grasp, hand.offsets[k]));
        }
    };
    // One servo step per pad: close fast until first contact, then hold the band.
    let servo = |world: &PhysicsWorld, hand: &mut Hand, squeezing: bool| {
        for k in 0..2 {
            let f = force(world, hand.pad_colliders[k]);
            let inward = if k == 0 { 1.0 } else { -1.0 };
            let speed = if squeezing && f < config.squeeze_n {
                if f > 0.0 {
                    config.servo_speed * 4.0
                } else {
                    config.close_speed
                }
            } else if f < config.hold_band_n.0 {
                config.servo_speed
            } else if f > config.hold_band_n.1 {
                -config.servo_speed
            } else {
                0.0
            };
            hand.offsets[k] += inward * speed * config.dt;
        }
    };

    // Close.
    let close_steps = ((opening / config.close_speed) / config.dt) as usize + 240;
    let mut gripped = false;
    for _ in 0..close_steps {
        servo(&world, &mut hand, true);
        if hand.offsets[1] - hand.offsets[0] < g.pad_thickness_m + 0.001 {
            return Trial {
                outcome: TrialOutcome::NoGrip,
                poses: poses(&world),
            };
        }
        place(&mut world, &hand, &grasp);
        world.step();
        if (0..2).all(|k| force(&world, hand.pad_colliders[k]) >= config.squeeze_n) {
            gripped = true;
            break;
        }
    }
    if !gripped {
        return Trial {
            outcome: TrialOutcome::NoGrip,
            poses: poses(&world),
        };
    }
    // Lift, then shake, servoing the grip all along.
    let lift_path: Vec<f32> =
        rest_to_rest(config.lift_m, config.lift_speed, config.lift_accel, config.dt).collect();
    let lift_steps = lift_path.len();
    let shake_steps = (config.shake_s / config.dt) as usize;
    let across = grasp.rotation * Vector::Y;
    for step in 0..lift_steps + shake_steps {
        // (No lift at all: lift_m 0 gives an empty path.)
        let rise = lift_path
            .get(step.min(lift_steps.saturating_sub(1)))
            .copied()
            .unwrap_or(0.0);
        let t = step.saturating_sub(lift_steps) as f32 * config.dt;
        // 1 - cos: from rest and back to rest, 2 x shake_m peak to peak.
        let sway = config.shake_m * (1.0 - (std::f32::consts::TAU * config.shake_hz * t).cos());
        let moved = Pose::from_translation(Vector::new(0.0, 0.0, rise) + across * sway) * grasp;
        servo(&world, &mut hand, false);
        place(&mut world, &hand, &moved);
        world.step();
    }
    let lifted = world.bodies[object].translation().z - start_z;
    let touching = (0..2).all(|k| force(&world, hand.pad_colliders[k]) > 0.0);
    let held = touching && lifted > 0.8 * config.lift_m;
    let outcome = match basket {
        _ if !held => TrialOutcome::Dropped { lifted_m: lifted },
        None => TrialOutcome::Held { lifted_m: lifted },
        Some(basket) => {
            let lifted_pose = Pose::from_translation(Vector::new(0.0, 0.0, config.lift_m)) * grasp;
            let servo_holding = |w: &PhysicsWorld, h: &mut Hand| servo(w, h, false);
            let motion = (
                &servo_holding as &dyn Fn(&PhysicsWorld, &mut Hand),
                &place as &Place<'_>,
            );
            if carry_and_release(
                &mut world,
                &mut hand,
                lifted_pose,
                object,
                &bodies,
                scene,
                &basket,
                motion,
                config,
            ) {
                TrialOutcome::Held { lifted_m: lifted }
            } else {
                TrialOutcome::Dropped { lifted_m: lifted }
            }
        }
    };
    Trial {
        outcome,
        poses: poses(&world),
    }
}

/// Carries the held `object` from `lifted` (the hand's pose) to the basket:
/// up until its bottom clears every other object and the basket's walls by
/// 3 cm, across, speeding up and slowing down at the basket's acceleration,
/// then opens the pads and waits.
/// True when the object came to rest inside the basket.
#[allow(clippy::too_many_arguments)] // the trial's state, passed on rather than rebuilt
fn carry_and_release(
    world: &mut PhysicsWorld,
    hand: &mut Hand,
    lifted: Pose,
    object: RigidBodyHandle,
    bodies: &[RigidBodyHandle],
    scene: &Scene,
    basket: &Basket,
    (servo, place): (&Servo<'_>, &Place<'_>),
    config: &TrialConfig,
) -> bool {
    let aabb_of = |world: &PhysicsWorld, b: RigidBodyHandle| {
        let body = &world.bodies[b];
        world.colliders[body.colliders()[0]].compute_aabb()
    };
    let start_z = scene.table_z;
    let others_top = bodies
        .iter()
        .filter(|&&b| b != object)
        .map(|&b| aabb_of(world, b).maxs.z)
        .fold(scene.table_z + basket.wall_m, f32::max);
    let below_hand = lifted.translation.z - aabb_of(world, object).mins.z;
    let carry_z = lifted.translation.z.max(others_top + 0.03 + below_hand);
    let [bx, by] = basket.centre_xy;
    let waypoints = [
        Vector::new(lifted.translation.x, lifted.translation.y, carry_z),
        Vector::new(bx, by, carry_z),
    ];
    let mut at = lifted.translation;
    for target in waypoints {
        let start = at;
        let leg = target - start;
        for travelled in rest_to_rest(leg.length(), basket.speed, basket.accel, config.dt) {
            at = start + leg * (travelled / leg.length());
            servo(world, hand);
            place(world, hand, &Pose::from_parts(at, lifted.rotation));
            world.step();
        }
        at = target;
    }
    // Open the pads (5 cm each at the closing speed), then let it fall and settle.
    let open_steps = (0.05 / config.close_speed / config.dt) as usize;
    let release_steps = (basket.release_s / config.dt) as usize;
    let pose = Pose::from_parts(at, lifted.rotation);
    for step in 0..open_steps + release_steps {
        if step < open_steps {
            hand.offsets[0] -= config.close_speed * config.dt;
            hand.offsets[1] += config.close_speed * config.dt;
        }
        place(world, hand, &pose);
        world.step();
    }
    let c = aabb_of(world, object).center();
    (c.x - bx).abs() < basket.inner_half_m
        && (c.y - by).abs() < basket.inner_half_m
        && c.z < start_z + basket.wall_m
}

/// Distance travelled after each step of `dt` along a straight leg of
/// `length` (m), from rest to rest: speeding up at `accel` (m/s^2) to
/// `speed` (m/s), cruising, and slowing down at `accel` so as to stop at the
/// end. The last value is `length`.
pub fn rest_to_rest(length: f32, speed: f32, accel: f32, dt: f32) -> impl Iterator<Item = f32> {
    let (mut travelled, mut v) = (0.0f32, 0.0f32);
    std::iter::from_fn(move || {
        let left = length - travelled;
        if left <= 1e-6 {
            return None;
        }
        // The fastest speed from which steps slowing by `accel * dt` each
        // stop within `left`: left = v^2 / (2 accel) + v dt / 2.
        let step = accel * dt;
        let braking = (-step + (step * step + 8.0 * accel * left).sqrt()) / 2.0;
        v = (v + step).min(speed).min(braking);
        // The braking bound reaches 0 only at the end: never stall short of it.
        travelled = (travelled + (v * dt).max(1e-5)).min(length);
        Some(travelled)
    })
}

/// How often analytic labels and physics trials agree on a sample of grasps.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Agreement {
    /// Analytic positive, held in physics.
    pub both_positive: usize,
    /// Analytic negative, not held.
    pub both_negative: usize,
    /// Analytic positive, not held.
    pub analytic_only: usize,
    /// Analytic negative, held.
    pub physics_only: usize,
}

impl Agreement {
    /// Grasps compared.
    pub fn total(&self) -> usize {
        self.both_positive + self.both_negative + self.analytic_only + self.physics_only
    }

    /// Share of grasps where both agree.
    pub fn rate(&self) -> f64 {
        (self.both_positive + self.both_negative) as f64 / self.total().max(1) as f64
    }
}

/// Compares analytic labels with physics on top-down grasps of the isolated
/// scenes `seeds`: for each, grasps through the object's centre at 8 yaws and
/// fingertips 1, 2.5 and 4 cm below its top, opened to the full stroke.
/// (A stated sample, not every candidate of every view.)
pub fn agreement(
    seeds: std::ops::Range<u64>,
    families: &[crate::objects::Family],
    gripper: &GripperModel,
    config: &TrialConfig,
) -> crate::Result<Agreement> {
    let mut a = Agreement::default();
    for seed in seeds {
        let scene = Scene::generate(crate::scene::Scenario::Isolated, seed, families)?;
        for k in 0..8 {
            let yaw = k as f64 * std::f64::consts::PI / 8.0;
            for depth in [0.01, 0.025, 0.04] {
                let grasp = crate::grasp::top_down_over(&scene.objects[0], yaw, depth, 0.0);
                let width = f64::from(gripper.max_width_m - gripper.clearance_m);
                let analytic = crate::grasp::label_grasp(&scene, 0, &grasp, width, gripper);
                // Grasps whose open hand already collides are negative both ways by construction.
                if matches!(
                    analytic,
                    crate::grasp::GraspLabel::Collision { .. } | crate::grasp::GraspLabel::TooWide
                ) {
                    continue;
                }
                let held = trial(&scene, 0, &grasp, width, gripper, config).is_held();
                match (analytic.is_positive(), held) {
                    (true, true) => a.both_positive += 1,
                    (false, false) => a.both_negative += 1,
                    (true, false) => a.analytic_only += 1,
                    (false, true) => a.physics_only += 1,
                }
            }
        }
    }
    Ok(a)
}
