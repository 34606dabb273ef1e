//! Piles and settling in rapier3d.
//!
//! A pile is the paper's third scenario: 4-6 objects dropped one above the
//! other into a box on the table, left to settle, the box lifted away, and
//! left to settle again. The objects end up leaning on and lying across each
//! other, which the placed scenarios never do.
//!
//! [`settle`] is also what happens to a pile between two grasps: when an
//! object is taken out, the ones that leaned on it fall into their new rest
//! (`eval` settles pile scenes after every removal).

use mvgrasp_core::rng::SplitMix64;
use parry3d::math::{Pose, Rotation, Vector};
use rapier3d::prelude::{ColliderBuilder, PhysicsWorld, RigidBodyBuilder, RigidBodyHandle};

use crate::objects::ObjectModel;
use crate::physics::{add_object, scene_world};
use crate::scene::{PlacedObject, Scene};

/// How settling runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SettleConfig {
    /// Step (s).
    pub dt: f32,
    /// Friction of objects, table and box.
    pub friction: f32,
    /// Give up waiting for rest after this long (s) in each phase.
    pub max_s: f32,
    /// An object rests below this speed (m/s) ...
    pub rest_speed_m_s: f32,
    /// ... and this spin (rad/s).
    pub rest_spin_rad_s: f32,
    /// Solver iterations per step (stacks need more than a grasp trial).
    pub solver_iterations: usize,
    /// Angular damping of the objects (1/s): rapier has no rolling
    /// resistance, and without it round objects roll off the table.
    pub angular_damping: f32,
}

impl Default for SettleConfig {
    fn default() -> Self {
        Self {
            dt: 1.0 / 240.0,
            friction: 0.8,
            max_s: 3.0,
            rest_speed_m_s: 0.005,
            rest_spin_rad_s: 0.05,
            solver_iterations: 12,
            angular_damping: 3.0,
        }
    }
}

/// The box a pile is dropped into: square, centred on the table's origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DropBox {
    /// Half the inner side (m).
    pub inner_half_m: f32,
    /// Wall height (m).
    pub height_m: f32,
}

impl Default for DropBox {
    fn default() -> Self {
        Self {
            inner_half_m: 0.11,
            height_m: 0.3,
        }
    }
}

/// The settling world of `scene`: more solver iterations and damped spin.
fn settling_world(scene: &Scene, config: &SettleConfig) -> (PhysicsWorld, Vec<RigidBodyHandle>) {
    let (mut world, bodies) = scene_world(scene, config.dt, config.friction);
    world.integration_parameters.num_solver_iterations = config.solver_iterations;
    for &b in &bodies {
        world.bodies[b].set_angular_damping(config.angular_damping);
    }
    (world, bodies)
}

/// Steps `world` until every body in `bodies` rests (checked every 1/10 s)
/// or `config.max_s` has passed.
fn run_to_rest(world: &mut PhysicsWorld, bodies: &[RigidBodyHandle], config: &SettleConfig) {
    let check_every = ((0.1 / config.dt) as usize).max(1);
    let max_steps = (config.max_s / config.dt) as usize;
    for step in 1..=max_steps {
        world.step();
        if step % check_every == 0
            && bodies.iter().all(|&h| {
                let b = &world.bodies[h];
                b.is_sleeping()
                    || (b.linvel().length() < config.rest_speed_m_s
                        && b.angvel().length() < config.rest_spin_rad_s)
            })
        {
            return;
        }
    }
}

/// Writes the bodies' poses back into `scene`, and drops the objects that
/// left the table (fell over its edge). Returns how many were dropped.
fn write_back(scene: &mut Scene, world: &PhysicsWorld, bodies: &[RigidBodyHandle]) -> usize {
    for (o, &h) in scene.objects.iter_mut().zip(bodies) {
        o.world_from_object = *world.bodies[h].position();
        o.world_aabb = o.model.aabb_at(&o.world_from_object);
    }
    let before = scene.objects.len();
    let (table_z, [hx, hy]) = (scene.table_z, scene.table_half);
    scene.objects.retain(|o| {
        let (lo, hi) = (o.world_aabb.mins, o.world_aabb.maxs);
        let centre = (lo + hi) * 0.5;
        lo.z > table_z - 0.02 && centre.x.abs() < hx && centre.y.abs() < hy
    });
    before - scene.objects.len()
}

/// Lets the scene's objects fall into rest under gravity on the table and
/// writes their new poses back. Objects that fall off the table are removed;
/// returns how many.
pub fn settle(scene: &mut Scene, config: &SettleConfig) -> usize {
    if scene.objects.is_empty() {
        return 0;
    }
    let (mut world, bodies) = settling_world(scene, config);
    run_to_rest(&mut world, &bodies, config);
    write_back(scene, &world, &bodies)
}

/// A rotation drawn uniformly (Shoemake's method).
fn random_rotation(rng: &mut SplitMix64) -> Rotation {
    let (u1, u2, u3) = (rng.next_f64(), rng.next_f64(), rng.next_f64());
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    Rotation::from_xyzw(
        (a * (tau * u2).sin()) as f32,
        (a * (tau * u2).cos()) as f32,
        (b * (tau * u3).sin()) as f32,
        (b * (tau * u3).cos()) as f32,
    )
    .normalize()
}

/// Drops `models` into `drop_box` on the table of `scene` (replacing any
/// objects it holds), one at a time in random orientations, each released
/// 2 cm over what is already in the box and left to come to rest (at most
/// `config.max_s`); then lifts the box away and lets the heap settle again.
/// Short falls keep impacts slow, so nothing tunnels into the table. The
/// result is in `scene.objects`; objects that fell off the table are not.
pub fn drop_pile(
    scene: &mut Scene,
    models: Vec<ObjectModel>,
    drop_box: &DropBox,
    config: &SettleConfig,
    rng: &mut SplitMix64,
) {
    scene.objects.clear();
    let (mut world, mut bodies) = settling_world(scene, config);
    // The box: four fixed walls around the drop area, removed at the end.
    let inner = drop_box.inner_half_m;
    let thickness = 0.01;
    let (h, t) = (drop_box.height_m / 2.0, thickness / 2.0);
    let walls =
        world.insert_body(RigidBodyBuilder::fixed().translation(Vector::new(0.0, 0.0, scene.table_z + h)));
    for (hx, hy, at) in [
        (t, inner + thickness, Vector::new(inner + t, 0.0, 0.0)),
        (t, inner + thickness, Vector::new(-inner - t, 0.0, 0.0)),
        (inner + thickness, t, Vector::new(0.0, inner + t, 0.0)),
        (inner + thickness, t, Vector::new(0.0, -inner - t, 0.0)),
    ] {
        let collider = ColliderBuilder::cuboid(hx, hy, h)
            .translation(at)
            .friction(config.friction);
        world.insert_collider(collider, Some(walls));
    }
    for model in models {
        let top = scene
            .objects
            .iter()
            .zip(&bodies)
            .map(|(o, &b)| o.model.aabb_at(world.bodies[b].position()).maxs.z)
            .fold(scene.table_z, f32::max);
        // An orientation that fits between the walls (a long object lies
        // along a diagonal or stands up), else the last one drawn.
        let mut rotation = random_rotation(rng);
        let mut turned = model.aabb_at(&Pose::from_rotation(rotation));
        for _ in 0..32 {
            let half = (turned.maxs - turned.mins) * 0.5;
            if half.x < inner && half.y < inner {
                break;
            }
            rotation = random_rotation(rng);
            turned = model.aabb_at(&Pose::from_rotation(rotation));
        }
        let half = (turned.maxs - turned.mins) * 0.5;
        let centre_in_model = (turned.mins + turned.maxs) * 0.5;
        let room = |h: f32| (inner - h).max(1e-4) as f64;
        let x = rng.uniform(-room(half.x), room(half.x)) as f32;
        let y = rng.uniform(-room(half.y), room(half.y)) as f32;
        let pose = Pose::from_parts(Vector::new(x, y, top + 0.02 + half.z) - centre_in_model, rotation);
        let object = PlacedObject {
            world_aabb: model.aabb_at(&pose),
            model,
            world_from_object: pose,
        };
        let body = add_object(&mut world, &object, config.friction);
        world.bodies[body].set_angular_damping(config.angular_damping);
        bodies.push(body);
        scene.objects.push(object);
        run_to_rest(&mut world, &bodies, config);
    }
    world.remove_body(walls);
    for &b in &bodies {
        world.wake_up(b, true);
    }
    run_to_rest(&mut world, &bodies, config);
    write_back(scene, &world, &bodies);
}

#[cfg(test)]
mod tests {
    use parry3d::query;

    use super::*;
    use crate::objects::Family;
    use crate::scene::Scenario;

    /// Per object of `scene`: the deepest interpenetration with any other
    /// (m, 0 if none) and whether another is within 3 mm.
    fn contacts(scene: &Scene) -> Vec<(f32, bool)> {
        let objects = &scene.objects;
        (0..objects.len())
            .map(|i| {
                let (a, mut deepest, mut touching) = (&objects[i], 0.0f32, false);
                for (j, b) in objects.iter().enumerate() {
                    if i == j {
                        continue;
                    }
                    let contact = query::contact(
                        &a.world_from_object,
                        a.model.shape.as_ref(),
                        &b.world_from_object,
                        b.model.shape.as_ref(),
                        0.003,
                    );
                    if let Ok(Some(c)) = contact {
                        touching = true;
                        deepest = deepest.max(-c.dist);
                    }
                }
                (deepest, touching)
            })
            .collect()
    }

    #[test]
    fn piles_settle_on_the_table_in_a_heap_without_interpenetration() {
        let (mut objects, mut touching, mut on_others) = (0, 0, 0);
        for seed in 0..6 {
            let scene = Scene::generate(Scenario::Pile, seed, &Family::ALL).unwrap();
            assert!(
                (3..=6).contains(&scene.objects.len()),
                "seed {seed}: {} objects",
                scene.objects.len()
            );
            for (i, (o, (overlap, touches))) in scene.objects.iter().zip(contacts(&scene)).enumerate() {
                assert!(
                    o.world_aabb.mins.z > scene.table_z - 0.003,
                    "seed {seed}: object {i} sinks into the table ({} under it)",
                    scene.table_z - o.world_aabb.mins.z
                );
                // Without the box the heap spreads, but stays near where it was dropped.
                let c = (o.world_aabb.mins + o.world_aabb.maxs) * 0.5;
                assert!(
                    c.x.abs() < 0.35 && c.y.abs() < 0.35,
                    "seed {seed}: object {i} at {c:?}"
                );
                assert!(
                    overlap < 0.005,
                    "seed {seed}: object {i} interpenetrates by {overlap} m"
                );
                objects += 1;
                touching += usize::from(touches);
                on_others += usize::from(o.world_aabb.mins.z > scene.table_z + 0.01);
            }
        }
        // A heap, not objects laid out apart: most touch another, some rest on others.
        assert!(
            2 * touching >= objects && on_others >= 2,
            "{touching} of {objects} objects touch another, {on_others} rest on others"
        );
    }

    #[test]
    fn the_same_seed_gives_the_same_pile() {
        let poses = |seed| -> Vec<[f32; 3]> {
            Scene::generate(Scenario::Pile, seed, &Family::ALL)
                .unwrap()
                .objects
                .iter()
                .map(|o| o.world_from_object.translation.to_array())
                .collect()
        };
        assert_eq!(poses(3), poses(3));
        assert_ne!(poses(3), poses(4));
    }

    #[test]
    fn taking_the_bottom_object_out_lets_the_ones_above_fall() {
        // A box on a box: remove the lower one and the upper one lands on the table.
        let mut scene = Scene::generate(Scenario::Isolated, 5, &[Family::Box]).unwrap();
        let lower = scene.objects[0].clone();
        let mut upper = lower.clone();
        let lift = lower.world_aabb.maxs.z - lower.world_aabb.mins.z;
        upper.world_from_object.translation.z += lift;
        upper.world_aabb = upper.model.aabb_at(&upper.world_from_object);
        scene.objects.push(upper);
        assert_eq!(settle(&mut scene, &SettleConfig::default()), 0);
        assert!(
            (scene.objects[1].world_aabb.mins.z - (scene.table_z + lift)).abs() < 0.005,
            "a box resting on a box stays there"
        );
        scene.objects.remove(0);
        settle(&mut scene, &SettleConfig::default());
        assert!(
            (scene.objects[0].world_aabb.mins.z - scene.table_z).abs() < 0.005,
            "the upper box fell to the table: bottom at {} for a table at {}",
            scene.objects[0].world_aabb.mins.z,
            scene.table_z
        );
    }
}
