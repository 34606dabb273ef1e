//! Scenes: objects resting on a table, laid out per scenario, deterministic
//! per seed. The table is the plane `z = table_z`, centred on the world
//! origin.

use mvgrasp_core::Workspace;
use mvgrasp_core::rng::SplitMix64;
use nalgebra::Point3;
use parry3d::bounding_volume::Aabb;
use parry3d::math::{Pose, Rotation, Vector};

use crate::error::{Error, Result};
use crate::objects::{Catalog, Family, ObjectModel};
use crate::pile::{DropBox, SettleConfig, drop_pile};

/// The paper's evaluation scenarios. The discriminants seed the scenes, so
/// a new scenario goes at the end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Scenario {
    /// One object, upright or toppled, anywhere near the table centre.
    Isolated,
    /// 4-6 upright objects placed close together (gaps of 8-25 mm).
    Packed,
    /// 15-20 objects, upright or toppled, spread over the table.
    Clutter,
    /// 4-6 objects dropped into a box, settled in rapier3d, the box lifted
    /// away and settled again (`pile.rs`).
    Pile,
}

impl Scenario {
    /// Every scenario.
    pub const ALL: [Scenario; 4] = [
        Scenario::Isolated,
        Scenario::Packed,
        Scenario::Pile,
        Scenario::Clutter,
    ];

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Isolated => "isolated",
            Self::Packed => "packed",
            Self::Clutter => "clutter",
            Self::Pile => "pile",
        }
    }

    /// The scenario called `name`.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// An object where it stands.
#[derive(Debug, Clone)]
pub struct PlacedObject {
    /// The object.
    pub model: ObjectModel,
    /// Its pose (the model's frame in the world).
    pub world_from_object: Pose,
    /// Its bounding box in the world.
    pub world_aabb: Aabb,
}

/// A table with objects on it.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Height of the table top (m).
    pub table_z: f32,
    /// Half sizes of the table top along x and y (m).
    pub table_half: [f32; 2],
    /// The objects; object `i` is labelled `2 + i` in rendered frames.
    pub objects: Vec<PlacedObject>,
    /// How it was laid out.
    pub scenario: Scenario,
    /// The seed that made it.
    pub seed: u64,
}

/// Half sizes of every scene's table top along x and y (m).
const TABLE_HALF: [f32; 2] = [0.6, 0.5];

/// Smallest gap between two objects' footprints in clutter (m): wider than
/// the planner's clustering tolerance (1 cm).
const CLUTTER_GAP_M: f64 = 0.012;

/// A resting pose of `model` on the table at `(x, y)`: upright, or toppled
/// onto a side, turned by `yaw`.
fn resting(model: &ObjectModel, table_z: f32, x: f32, y: f32, yaw: f32, toppled: Option<u8>) -> (Pose, Aabb) {
    let tilt = match toppled {
        None => Rotation::IDENTITY,
        Some(0) => Rotation::from_rotation_x(std::f32::consts::FRAC_PI_2),
        Some(1) => Rotation::from_rotation_x(-std::f32::consts::FRAC_PI_2),
        Some(2) => Rotation::from_rotation_y(std::f32::consts::FRAC_PI_2),
        Some(_) => Rotation::from_rotation_y(-std::f32::consts::FRAC_PI_2),
    };
    let rotation = Rotation::from_rotation_z(yaw) * tilt;
    let turned = model.shape.compute_aabb(&Pose::from_rotation(rotation));
    // Centre the footprint on (x, y) and put the lowest point on the table.
    let centre = (turned.mins + turned.maxs) * 0.5;
    let translation = Vector::new(x - centre.x, y - centre.y, table_z - turned.mins.z);
    let pose = Pose::from_parts(translation, rotation);
    (pose, model.shape.compute_aabb(&pose))
}

/// Footprint radius of a placed object around its box centre.
fn radius(aabb: &Aabb) -> f64 {
    let half = (aabb.maxs - aabb.mins) * 0.5;
    f64::from((half.x * half.x + half.y * half.y).sqrt())
}

fn centre_xy(aabb: &Aabb) -> (f64, f64) {
    let c = (aabb.mins + aabb.maxs) * 0.5;
    (f64::from(c.x), f64::from(c.y))
}

/// Whether `candidate`'s footprint (its world box in x, y) keeps `gap` from
/// every placed object's.
fn fits(placed: &[PlacedObject], candidate: &Aabb, gap: f64) -> bool {
    let gap = gap as f32;
    placed.iter().all(|p| {
        let (a, b) = (&p.world_aabb, candidate);
        a.maxs.x + gap <= b.mins.x
            || b.maxs.x + gap <= a.mins.x
            || a.maxs.y + gap <= b.mins.y
            || b.maxs.y + gap <= a.mins.y
    })
}

impl Scene {
    /// The box the planner should look in: the table top, from 5 cm under
    /// it to 50 cm over it.
    pub fn workspace(&self) -> Workspace {
        let (z, hx, hy) = (
            f64::from(self.table_z),
            f64::from(self.table_half[0]),
            f64::from(self.table_half[1]),
        );
        Workspace {
            min: Point3::new(-hx, -hy, z - 0.05),
            max: Point3::new(hx, hy, z + 0.5),
        }
    }

    /// This scene with object `object` alone on the table, where it is (it
    /// becomes object 0). Labels on it say what the object's own shape
    /// allows, whatever stands around it.
    pub fn only(&self, object: usize) -> Scene {
        Scene {
            objects: vec![self.objects[object].clone()],
            ..self.clone()
        }
    }

    /// The object whose world box, grown by `margin_m`, holds `point`; of
    /// several, the one whose box centre is nearest. How a detection (its
    /// centroid) is matched to the scene object it is.
    pub fn object_at(&self, point: &Point3<f64>, margin_m: f32) -> Option<usize> {
        let p = Vector::new(point.x as f32, point.y as f32, point.z as f32);
        self.objects
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                let (lo, hi) = (o.world_aabb.mins, o.world_aabb.maxs);
                (0..3).all(|k| p[k] >= lo[k] - margin_m && p[k] <= hi[k] + margin_m)
            })
            .min_by(|(_, a), (_, b)| {
                let d = |o: &PlacedObject| ((o.world_aabb.mins + o.world_aabb.maxs) * 0.5 - p).length();
                d(a).total_cmp(&d(b))
            })
            .map(|(i, _)| i)
    }

    /// The scene of `scenario` for `seed`, drawing objects from `families`.
    pub fn generate(scenario: Scenario, seed: u64, families: &[Family]) -> Result<Self> {
        Self::generate_from(scenario, seed, &Catalog::of(families))
    }

    /// The scene of `scenario` for `seed`, drawing objects from `catalog`.
    pub fn generate_from(scenario: Scenario, seed: u64, catalog: &Catalog) -> Result<Self> {
        if catalog.is_empty() {
            return Err(Error::Invalid {
                field: "families",
                reason: "at least one shape family or mesh is needed".into(),
            });
        }
        let mut rng = SplitMix64::new(seed ^ 0x5CE4_E5B9_0000_0000 ^ scenario as u64);
        let table_z = rng.uniform(-0.1, 0.9) as f32;
        let mut objects: Vec<PlacedObject> = Vec::new();
        let (count, spread, upright_only) = match scenario {
            Scenario::Isolated => (1, 0.10, false),
            Scenario::Packed => (4 + rng.below(3), 0.0, true),
            Scenario::Clutter => (15 + rng.below(6), 0.0, false),
            Scenario::Pile => {
                let count = 4 + rng.below(3);
                let models = (0..count)
                    .map(|_| catalog.draw(&mut rng))
                    .collect::<Result<Vec<_>>>()?;
                let mut scene = Self {
                    table_z,
                    table_half: TABLE_HALF,
                    objects: Vec::new(),
                    scenario,
                    seed,
                };
                let settle = SettleConfig::default();
                drop_pile(&mut scene, models, &DropBox::default(), &settle, &mut rng);
                return Ok(scene);
            }
        };
        let mut attempts = 0;
        let mut current: Option<ObjectModel> = None;
        while objects.len() < count {
            attempts += 1;
            if attempts > 20_000 {
                return Err(Error::Scene(format!(
                    "{} seed {seed}: placed {} of {count} objects",
                    scenario.name(),
                    objects.len()
                )));
            }
            // A new object every 50 failed tries, so a crowded table gets the ones that fit.
            if attempts % 50 == 1 || current.is_none() {
                current = Some(catalog.draw(&mut rng)?);
            }
            let Some(model) = current.clone() else { continue };
            let yaw = rng.uniform(0.0, std::f64::consts::TAU) as f32;
            let toppled = (!upright_only && rng.next_f64() < 0.4).then(|| rng.below(4) as u8);
            let (x, y) = match scenario {
                Scenario::Isolated | Scenario::Pile => {
                    (rng.uniform(-spread, spread), rng.uniform(-spread, spread))
                }
                Scenario::Clutter => (rng.uniform(-0.4, 0.4), rng.uniform(-0.32, 0.32)),
                Scenario::Packed if objects.is_empty() => {
                    (rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05))
                }
                Scenario::Packed => {
                    // Next to a random placed object, at a small gap.
                    let anchor = &objects[rng.below(objects.len())];
                    let (ax, ay) = centre_xy(&anchor.world_aabb);
                    let probe = resting(&model, table_z, 0.0, 0.0, yaw, None).1;
                    let d = radius(&anchor.world_aabb) + radius(&probe) + rng.uniform(0.008, 0.025);
                    let a = rng.uniform(0.0, std::f64::consts::TAU);
                    (ax + d * a.cos(), ay + d * a.sin())
                }
            };
            let (pose, aabb) = resting(&model, table_z, x as f32, y as f32, yaw, toppled);
            let gap = if scenario == Scenario::Packed {
                0.006
            } else {
                CLUTTER_GAP_M
            };
            if fits(&objects, &aabb, gap) {
                current = None;
                objects.push(PlacedObject {
                    model,
                    world_from_object: pose,
                    world_aabb: aabb,
                });
            }
        }
        Ok(Self {
            table_z,
            table_half: TABLE_HALF,
            objects,
            scenario,
            seed,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenes_rest_on_the_table_without_overlap() {
        // Piles are checked in pile.rs: their objects rest on each other.
        for scenario in [Scenario::Isolated, Scenario::Packed, Scenario::Clutter] {
            for seed in 0..6 {
                let scene = Scene::generate(scenario, seed, &Family::ALL).unwrap();
                let n = scene.objects.len();
                match scenario {
                    Scenario::Isolated => assert_eq!(n, 1),
                    Scenario::Packed => assert!((4..=6).contains(&n)),
                    Scenario::Clutter => assert!((15..=20).contains(&n)),
                    Scenario::Pile => unreachable!(),
                }
                for (i, o) in scene.objects.iter().enumerate() {
                    assert!(
                        (o.world_aabb.mins.z - scene.table_z).abs() < 1e-4,
                        "object {i} floats or sinks"
                    );
                    assert!(
                        fits(&scene.objects[i + 1..], &o.world_aabb, 0.0),
                        "object {i} overlaps"
                    );
                }
            }
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_scene() {
        let a = Scene::generate(Scenario::Clutter, 7, &Family::ALL).unwrap();
        let b = Scene::generate(Scenario::Clutter, 7, &Family::ALL).unwrap();
        let c = Scene::generate(Scenario::Clutter, 8, &Family::ALL).unwrap();
        let poses = |s: &Scene| -> Vec<[f32; 3]> {
            s.objects
                .iter()
                .map(|o| o.world_from_object.translation.to_array())
                .collect()
        };
        assert_eq!(poses(&a), poses(&b));
        assert_ne!(poses(&a), poses(&c));
    }
}
