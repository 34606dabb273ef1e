//! Procedural household-like objects: shape families with realistic sizes,
//! each a compound of convex parts (round surfaces as 32-sided hulls, as
//! physics wants them), in a local frame with z up and the origin at the
//! centre of the object's bottom.

use std::f32::consts::TAU;

use mvgrasp_core::rng::SplitMix64;
use parry3d::bounding_volume::Aabb;
use parry3d::math::{Pose, Vector};
use parry3d::shape::SharedShape;

use crate::error::{Error, Result};

/// Sides of round parts.
const SEGMENTS: usize = 32;

/// The shape families.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Family {
    /// A rectangular box.
    Box,
    /// An upright cylinder.
    Cylinder,
    /// A sphere or ellipsoid.
    Ellipsoid,
    /// A convex superquadric (rounded box / pillow shapes).
    Superquadric,
    /// A bottle: body, shoulder, neck.
    Bottle,
    /// A mug: hollow body and a handle.
    Mug,
    /// A bowl: a thin conical wall on a base.
    Bowl,
    /// Two boxes in an L.
    LShape,
    /// Two boxes in a T.
    TShape,
    /// A user mesh (`mesh.rs`): not procedural, so not in [`Family::ALL`];
    /// scenes get meshes from a [`Catalog`].
    Mesh,
}

impl Family {
    /// Every family.
    pub const ALL: [Family; 9] = [
        Family::Box,
        Family::Cylinder,
        Family::Ellipsoid,
        Family::Superquadric,
        Family::Bottle,
        Family::Mug,
        Family::Bowl,
        Family::LShape,
        Family::TShape,
    ];

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Box => "box",
            Self::Cylinder => "cylinder",
            Self::Ellipsoid => "ellipsoid",
            Self::Superquadric => "superquadric",
            Self::Bottle => "bottle",
            Self::Mug => "mug",
            Self::Bowl => "bowl",
            Self::LShape => "l_shape",
            Self::TShape => "t_shape",
            Self::Mesh => "mesh",
        }
    }

    /// The family called `name`.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }
}

/// One object: its convex parts and what placement and physics need.
#[derive(Clone)]
pub struct ObjectModel {
    /// The family.
    pub family: Family,
    /// The family's name, or a mesh's file stem.
    pub name: String,
    /// Convex parts in the object's frame.
    pub parts: Vec<(Pose, SharedShape)>,
    /// The parts as one compound shape.
    pub shape: SharedShape,
    /// Bounding box in the object's frame.
    pub aabb: Aabb,
    /// Mass (kg), from the parts' volume at a household density.
    pub mass_kg: f32,
    /// Centre of mass in the object's frame (uniform density, as the
    /// physics has it).
    pub local_com: Vector,
}

impl std::fmt::Debug for ObjectModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectModel")
            .field("name", &self.name)
            .field("parts", &self.parts.len())
            .field("aabb", &self.aabb)
            .field("mass_kg", &self.mass_kg)
            .finish()
    }
}

fn v(x: f32, y: f32, z: f32) -> Vector {
    Vector::new(x, y, z)
}

fn hull(points: &[Vector], what: &str) -> Result<SharedShape> {
    SharedShape::convex_hull(points).ok_or_else(|| Error::Shape(format!("{what}: degenerate convex hull")))
}

/// A ring of `SEGMENTS` points of radii `(rx, ry)` at height `z`.
fn ring(rx: f32, ry: f32, z: f32) -> impl Iterator<Item = Vector> {
    (0..SEGMENTS).map(move |i| {
        let a = i as f32 / SEGMENTS as f32 * TAU;
        v(rx * a.cos(), ry * a.sin(), z)
    })
}

/// A convex frustum between radius `r0` at `z0` and `r1` at `z1`.
fn frustum(r0: f32, z0: f32, r1: f32, z1: f32) -> Result<SharedShape> {
    let points: Vec<Vector> = ring(r0, r0, z0).chain(ring(r1, r1, z1)).collect();
    hull(&points, "frustum")
}

/// A thin wall between radii (inner, outer) at `z0` and at `z1`, cut into
/// `n` convex segments (a hollow body is not convex).
fn wall(
    n: usize,
    (in0, out0, z0): (f32, f32, f32),
    (in1, out1, z1): (f32, f32, f32),
) -> Result<Vec<SharedShape>> {
    (0..n)
        .map(|i| {
            let (a0, a1) = (i as f32 / n as f32 * TAU, (i + 1) as f32 / n as f32 * TAU);
            let mut points = Vec::with_capacity(8);
            for a in [a0, a1] {
                let (c, s) = (a.cos(), a.sin());
                for (r, z) in [(in0, z0), (out0, z0), (in1, z1), (out1, z1)] {
                    points.push(v(r * c, r * s, z));
                }
            }
            hull(&points, "wall segment")
        })
        .collect()
}

fn cuboid_at(centre: Vector, half: Vector) -> (Pose, SharedShape) {
    (
        Pose::from_translation(centre),
        SharedShape::cuboid(half.x, half.y, half.z),
    )
}

fn at_origin(shape: SharedShape) -> (Pose, SharedShape) {
    (Pose::identity(), shape)
}

/// Household density used for masses (kg/m^3): light, like packaged goods.
const DENSITY: f32 = 400.0;

impl ObjectModel {
    /// An object of `family` made of `parts` (convex shapes in the object frame, z up, bottom at z = 0).
    pub fn from_parts(family: Family, parts: Vec<(Pose, SharedShape)>) -> Self {
        let shape = SharedShape::compound(parts.clone());
        let aabb = shape.compute_local_aabb();
        let volume: f32 = parts.iter().map(|(_, s)| s.mass_properties(1.0).mass()).sum();
        let local_com = shape.mass_properties(1.0).local_com;
        Self {
            family,
            name: family.name().to_owned(),
            parts,
            shape,
            aabb,
            mass_kg: (volume * DENSITY).max(0.02),
            local_com,
        }
    }

    /// The tight bounding box of the object at `pose`: the union of its
    /// parts' boxes. (`shape.compute_aabb` turns the compound's local box,
    /// which is loose under any rotation that is not a quarter turn.)
    pub fn aabb_at(&self, pose: &Pose) -> Aabb {
        self.parts
            .iter()
            .map(|(part_pose, part)| part.compute_aabb(&(*pose * *part_pose)))
            .reduce(|a, b| Aabb::new(a.mins.min(b.mins), a.maxs.max(b.maxs)))
            .unwrap_or_else(|| self.shape.compute_aabb(pose))
    }

    /// A random object of `family`, with sizes drawn from `rng`. At least one
    /// way across every object is narrower than 12 cm (it fits a 2F-140).
    pub fn sample(family: Family, rng: &mut SplitMix64) -> Result<Self> {
        let mut u = |lo: f64, hi: f64| rng.uniform(lo, hi) as f32;
        let parts = match family {
            Family::Mesh => {
                return Err(Error::Shape(
                    "mesh objects are loaded from files (mesh.rs), not sampled".into(),
                ));
            }
            Family::Box => {
                let (a, b, h) = (u(0.03, 0.10), u(0.04, 0.20), u(0.04, 0.20));
                vec![cuboid_at(v(0.0, 0.0, h / 2.0), v(a / 2.0, b / 2.0, h / 2.0))]
            }
            Family::Cylinder => {
                let (r, h) = (u(0.02, 0.05), u(0.05, 0.20));
                vec![at_origin(frustum(r, 0.0, r, h)?)]
            }
            Family::Ellipsoid => {
                let (a, b, c) = (u(0.025, 0.06), u(0.025, 0.08), u(0.025, 0.06));
                let mut points = Vec::new();
                for k in 0..=12 {
                    let phi = k as f32 / 12.0 * std::f32::consts::PI;
                    points.extend(ring(a * phi.sin(), b * phi.sin(), c * (1.0 - phi.cos())));
                }
                vec![at_origin(hull(&points, "ellipsoid")?)]
            }
            Family::Superquadric => {
                let (a, b, c) = (u(0.025, 0.06), u(0.03, 0.08), u(0.025, 0.06));
                let (e1, e2) = (u(0.3, 1.0), u(0.3, 1.0));
                // Signed power: convex for exponents <= 1 (what is drawn here).
                let p = |x: f32, e: f32| x.signum() * x.abs().powf(e);
                let mut points = Vec::new();
                for k in 0..=16 {
                    let eta = -std::f32::consts::FRAC_PI_2 + k as f32 / 16.0 * std::f32::consts::PI;
                    for i in 0..SEGMENTS {
                        let w = -std::f32::consts::PI + i as f32 / SEGMENTS as f32 * TAU;
                        points.push(v(
                            a * p(eta.cos(), e1) * p(w.cos(), e2),
                            b * p(eta.cos(), e1) * p(w.sin(), e2),
                            c + c * p(eta.sin(), e1),
                        ));
                    }
                }
                vec![at_origin(hull(&points, "superquadric")?)]
            }
            Family::Bottle => {
                let (r, h) = (u(0.025, 0.045), u(0.10, 0.18));
                let (rn, hn, shoulder) = (u(0.010, 0.018), u(0.03, 0.06), u(0.015, 0.03));
                vec![
                    at_origin(frustum(r, 0.0, r, h)?),
                    at_origin(frustum(r, h, rn, h + shoulder)?),
                    at_origin(frustum(rn, h + shoulder, rn, h + shoulder + hn)?),
                ]
            }
            Family::Mug => {
                let (r, h, t) = (u(0.035, 0.05), u(0.07, 0.12), u(0.004, 0.007));
                let bottom = 0.008;
                let mut parts: Vec<(Pose, SharedShape)> = wall(12, (r - t, r, bottom), (r - t, r, h))?
                    .into_iter()
                    .map(at_origin)
                    .collect();
                parts.push(at_origin(frustum(r, 0.0, r, bottom)?));
                // The handle: a C of three bars on the +x side.
                let (reach, grip, bar) = (u(0.025, 0.035), h * 0.55, 0.006);
                let z0 = h * 0.2;
                parts.push(cuboid_at(v(r + reach / 2.0, 0.0, z0), v(reach / 2.0, bar, bar)));
                parts.push(cuboid_at(
                    v(r + reach / 2.0, 0.0, z0 + grip),
                    v(reach / 2.0, bar, bar),
                ));
                parts.push(cuboid_at(
                    v(r + reach, 0.0, z0 + grip / 2.0),
                    v(bar, bar, grip / 2.0 + bar),
                ));
                parts
            }
            Family::Bowl => {
                let (top, h, t) = (u(0.06, 0.09), u(0.04, 0.07), u(0.004, 0.007));
                let base_r = top * u(0.5, 0.65);
                let bottom = 0.006;
                let mut parts: Vec<(Pose, SharedShape)> =
                    wall(16, (base_r - t, base_r, bottom), (top - t, top, h))?
                        .into_iter()
                        .map(at_origin)
                        .collect();
                parts.push(at_origin(frustum(base_r, 0.0, base_r, bottom)?));
                parts
            }
            Family::LShape | Family::TShape => {
                let (t, h) = (u(0.03, 0.06), u(0.03, 0.10));
                let (l1, l2) = (u(0.08, 0.18), u(0.06, 0.14));
                let stem_x = if family == Family::LShape {
                    -l1 / 2.0 + t / 2.0
                } else {
                    0.0
                };
                vec![
                    cuboid_at(v(0.0, 0.0, h / 2.0), v(l1 / 2.0, t / 2.0, h / 2.0)),
                    cuboid_at(
                        v(stem_x, t / 2.0 + l2 / 2.0, h / 2.0),
                        v(t / 2.0, l2 / 2.0, h / 2.0),
                    ),
                ]
            }
        };
        Ok(Self::from_parts(family, parts))
    }

    /// Radius of the object's footprint around its origin (m), for spacing.
    pub fn footprint_radius(&self) -> f32 {
        let (lo, hi) = (self.aabb.mins, self.aabb.maxs);
        let x = lo.x.abs().max(hi.x.abs());
        let y = lo.y.abs().max(hi.y.abs());
        (x * x + y * y).sqrt()
    }
}

/// Where scenes draw their objects from: procedural families (a new
/// instance each draw) and loaded meshes (as they are).
#[derive(Debug, Clone, Default)]
pub struct Catalog {
    /// Procedural families.
    pub families: Vec<Family>,
    /// Mesh objects ([`crate::mesh::load_meshes`]).
    pub meshes: Vec<ObjectModel>,
}

impl Catalog {
    /// Procedural families only.
    pub fn of(families: &[Family]) -> Self {
        Self {
            families: families.to_vec(),
            meshes: Vec::new(),
        }
    }

    /// Nothing to draw from.
    pub fn is_empty(&self) -> bool {
        self.families.is_empty() && self.meshes.is_empty()
    }

    /// One object, every family and every mesh equally likely. With no
    /// meshes this draws exactly what `ObjectModel::sample` of a uniformly
    /// drawn family does, so family-only scenes do not change.
    pub fn draw(&self, rng: &mut SplitMix64) -> Result<ObjectModel> {
        if self.is_empty() {
            return Err(Error::Invalid {
                field: "families",
                reason: "no shape family and no mesh to draw objects from".into(),
            });
        }
        let k = rng.below(self.families.len() + self.meshes.len());
        match self.families.get(k) {
            Some(&family) => ObjectModel::sample(family, rng),
            None => Ok(self.meshes[k - self.families.len()].clone()),
        }
    }

    /// Names of the families and meshes, for manifests and reports.
    pub fn names(&self) -> Vec<String> {
        let families = self.families.iter().map(|f| f.name().to_owned());
        families
            .chain(self.meshes.iter().map(|m| format!("mesh:{}", m.name)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_family_builds_with_realistic_sizes() {
        let mut rng = SplitMix64::new(3);
        for family in Family::ALL {
            for _ in 0..20 {
                let o = ObjectModel::sample(family, &mut rng).unwrap();
                let size = o.aabb.maxs - o.aabb.mins;
                assert!(o.aabb.mins.z.abs() < 1e-4, "{family:?}: bottom at z = 0");
                assert!(
                    size.min_element() >= 0.02 && size.max_element() <= 0.40,
                    "{family:?}: {size:?}"
                );
                // Some way across fits the gripper (smallest horizontal extent, or the wall of a bowl).
                let narrow = size.x.min(size.y);
                // (An L or T fits across either bar, a bowl across its wall.)
                let across_a_part = matches!(family, Family::Bowl | Family::LShape | Family::TShape);
                assert!(narrow <= 0.14 || across_a_part, "{family:?}: {size:?}");
                assert!(o.mass_kg > 0.0 && o.mass_kg < 3.0, "{family:?}: {} kg", o.mass_kg);
                assert_eq!(Family::parse(family.name()), Some(family));
            }
        }
    }
}
