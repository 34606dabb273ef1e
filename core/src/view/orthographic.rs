//! Orthographic virtual depth views of one object (DESIGN.md, method step 3).
//!
//! A view looks at the object's centroid along one axis of the object frame.
//! Its own frame has x = image u (right), y = image v (down) and z = the
//! viewing direction (into the object), right-handed:
//!
//! | view    | looks along (object frame)                  | u     | v  |
//! |---------|---------------------------------------------|-------|----|
//! | `Top`   | -Z                                          | +X    | -Y |
//! | `Front` | -X (from the +X side, which faces the camera) | +Y  | -Z |
//! | `Side`  | -Y or +Y, from whichever side faces the camera | -X or +X | -Z |
//!
//! Pixels have a fixed metric size (the model contract's `pixel_size_m`), so a
//! width in pixels is a width in metres. Pixel `(u, v)` covers view-frame
//! `x` in `[(u - l/2) s, (u + 1 - l/2) s)`, likewise `y`.
//!
//! **Z-buffer.** Each pixel keeps the nearest point (smallest view z).
//!
//! **Holes.** Points are sparser than pixels where the camera saw a surface
//! at a grazing angle. One pass fills an empty pixel when at least
//! [`HOLE_FILL_MIN_NEIGHBOURS`] of its 8 neighbours hold a surface, with the
//! nearest of those depths; it reads the unfilled buffer, so the result does
//! not depend on scan order and a fill never spreads. Larger empty areas are
//! left empty: they are surfaces the camera did not see, and the network
//! must not be shown invented ones.
//!
//! **Normalisation `cube-v1`.** The view sees a cube of side `L = l s` centred
//! on the centroid. A filled pixel's value is `(L/2 - z) / L` clamped to
//! [0, 1]: 1 at the cube face nearest the viewer, 0.5 at the centroid, 0 at
//! the far face. Empty pixels are 0.

use nalgebra::{Matrix3, Vector3};

use crate::select::EntropySums;

/// Empty pixels with at least this many filled 8-neighbours are filled.
pub const HOLE_FILL_MIN_NEIGHBOURS: usize = 5;

/// Which virtual camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ViewAxis {
    /// Looking down along -Z.
    Top,
    /// Looking along -X, at the side facing the camera.
    Front,
    /// Looking along +-Y, at the side facing the camera.
    Side,
}

impl ViewAxis {
    /// The paper's three views, in their canonical order.
    pub const ALL: [ViewAxis; 3] = [ViewAxis::Top, ViewAxis::Front, ViewAxis::Side];

    /// Lower-case name, for logs and metrics.
    pub fn name(self) -> &'static str {
        match self {
            Self::Top => "top",
            Self::Front => "front",
            Self::Side => "side",
        }
    }

    /// Columns (u, v, viewing direction) in the object frame. `camera_on_plus_y`
    /// says which Y side the camera saw; only `Side` depends on it.
    pub fn object_from_view(self, camera_on_plus_y: bool) -> Matrix3<f64> {
        let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
        let (u, v, d) = match self {
            Self::Top => (x, -y, -z),
            Self::Front => (y, -z, -x),
            Self::Side if camera_on_plus_y => (-x, -z, -y),
            Self::Side => (x, -z, y),
        };
        Matrix3::from_columns(&[u, v, d])
    }
}

/// One rendered view.
#[derive(Debug, Clone, PartialEq)]
pub struct OrthoView {
    /// Which view.
    pub axis: ViewAxis,
    /// Columns: image u, image v and viewing direction, in the object frame.
    pub object_from_view: Matrix3<f64>,
    /// Side in pixels.
    pub size_px: usize,
    /// Metric pixel size (m).
    pub pixel_size_m: f32,
    /// Network input, `cube-v1` normalised, row-major.
    pub image: Vec<f32>,
    /// View-frame z of the kept surface (m), `+inf` where empty, row-major.
    pub depth_m: Vec<f32>,
    /// Viewpoint entropy of `image` (bits), as [`crate::select::view_entropy`] computes it.
    pub entropy: f64,
}

impl OrthoView {
    /// Renders the object points (object frame) into a `size_px` square view.
    pub fn render(
        axis: ViewAxis,
        camera_on_plus_y: bool,
        points_in_object: &[[f32; 3]],
        size_px: usize,
        pixel_size_m: f32,
    ) -> Self {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in points_in_object {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        Self::render_within(
            axis,
            camera_on_plus_y,
            points_in_object,
            (lo, hi),
            size_px,
            pixel_size_m,
        )
    }

    /// [`OrthoView::render`] for points known to lie in the object-frame box
    /// `extent` (`(min, max)`, e.g. the [`crate::ObjectFrame`]'s extent), which
    /// saves a pass: the box bounds the pixels that can hold a surface.
    /// A box larger than the points' gives the same view, only slower; one
    /// that misses points gives a wrong view (never a panic).
    pub fn render_within(
        axis: ViewAxis,
        camera_on_plus_y: bool,
        points_in_object: &[[f32; 3]],
        extent: ([f32; 3], [f32; 3]),
        size_px: usize,
        pixel_size_m: f32,
    ) -> Self {
        let object_from_view = axis.object_from_view(camera_on_plus_y);
        // Every view axis is +- one object axis: a signed permutation, no matrix product.
        let axis_of = |column: usize| {
            let c = object_from_view.column(column);
            let j = c.iamax();
            (j, c[j].signum() as f32)
        };
        let [(ju, su), (jv, sv), (jd, sd)] = [axis_of(0), axis_of(1), axis_of(2)];
        let l = size_px;
        let inv = 1.0 / pixel_size_m;
        let half = l as f32 * 0.5;
        let (su, sv) = (su * inv, sv * inv);
        let mut depth = vec![f32::INFINITY; l * l];
        // The pixels the extent covers (clamped to the image): every filled
        // pixel lies in it, as the view axes are signed object axes.
        let (lo, hi) = extent;
        let side = l as f32;
        let span = |j: usize, scale: f32| {
            let (a, b) = (scale * lo[j] + half, scale * hi[j] + half);
            (a.min(b), a.max(b))
        };
        let (su_span, sv_span) = (span(ju, su), span(jv, sv));
        // Every point projects inside the image: the per-point test can go.
        let inside = [su_span, sv_span].iter().all(|&(a, b)| a >= 0.0 && b < side);
        let pixel_range = |(a, b): (f32, f32)| {
            let (a, b) = (a.max(0.0), b.min(side - 1.0));
            (a as usize, b as usize)
        };
        let ((u0, u1), (v0, v1)) = (pixel_range(su_span), pixel_range(sv_span));
        let filled_box = if points_in_object.is_empty() || u0 > u1 || v0 > v1 || l == 0 {
            PixelBox::EMPTY
        } else {
            PixelBox { u0, u1, v0, v1 }
        };
        let projection = Projection {
            su,
            sv,
            sd,
            half,
            side,
            l,
        };
        // One loop per axis permutation, so the coordinates are fixed loads.
        match (ju, jv, jd) {
            (0, 1, 2) => projection.splat::<0, 1, 2>(points_in_object, inside, &mut depth),
            (1, 2, 0) => projection.splat::<1, 2, 0>(points_in_object, inside, &mut depth),
            (0, 2, 1) => projection.splat::<0, 2, 1>(points_in_object, inside, &mut depth),
            _ => projection.splat_any([ju, jv, jd], points_in_object, &mut depth),
        }
        fill_holes(&mut depth, l, &filled_box);
        // Every surface pixel lies in the box (holes are filled inside it):
        // normalise, and sum the entropy, there only.
        let cube = l as f32 * pixel_size_m;
        let mut image = vec![0.0f32; l * l];
        let mut entropy = EntropySums::default();
        if filled_box.u0 <= filled_box.u1 {
            for v in filled_box.v0..=filled_box.v1 {
                let row = v * l;
                for i in row + filled_box.u0..=row + filled_box.u1 {
                    let z = depth[i];
                    if z.is_finite() {
                        let value = ((0.5 * cube - z) / cube).clamp(0.0, 1.0);
                        image[i] = value;
                        entropy.add(value);
                    }
                }
            }
        }
        Self {
            axis,
            object_from_view,
            size_px: l,
            pixel_size_m,
            image,
            depth_m: depth,
            entropy: entropy.bits(),
        }
    }

    /// Object-frame point at continuous pixel coordinates `(u, v)` (pixel
    /// centres at `i + 0.5`) and view depth `z_m`.
    pub fn point_in_object(&self, u: f64, v: f64, z_m: f64) -> Vector3<f64> {
        let s = f64::from(self.pixel_size_m);
        let half = self.size_px as f64 * 0.5;
        self.object_from_view * Vector3::new((u - half) * s, (v - half) * s, z_m)
    }

    /// Continuous pixel coordinates and view depth of an object-frame point.
    pub fn pixel_of(&self, p_in_object: &Vector3<f64>) -> (f64, f64, f64) {
        let q = self.object_from_view.transpose() * p_in_object;
        let s = f64::from(self.pixel_size_m);
        let half = self.size_px as f64 * 0.5;
        (q.x / s + half, q.y / s + half, q.z)
    }

    /// Nearest surface depth within `radius_m` of pixel `(u, v)` (pixel
    /// indices), or `None` when no pixel there holds a surface.
    pub fn nearest_depth_within(&self, u: usize, v: usize, radius_m: f32) -> Option<f32> {
        let r = (radius_m / self.pixel_size_m).floor() as isize;
        let l = self.size_px as isize;
        let mut best = f32::INFINITY;
        for dv in -r..=r {
            for du in -r..=r {
                if du * du + dv * dv > r * r {
                    continue;
                }
                let (x, y) = (u as isize + du, v as isize + dv);
                if x < 0 || y < 0 || x >= l || y >= l {
                    continue;
                }
                best = best.min(self.depth_m[(y * l + x) as usize]);
            }
        }
        best.is_finite().then_some(best)
    }
}

/// The z-buffer splat of one view: pixel = scaled signed object coordinates.
struct Projection {
    su: f32,
    sv: f32,
    sd: f32,
    half: f32,
    side: f32,
    l: usize,
}

impl Projection {
    /// `CHECK`: whether points can fall outside the image (else the caller
    /// knows from the extent that none does, and the test is skipped).
    #[inline(always)]
    fn splat_one<const CHECK: bool>(&self, (pu, pv, pd): (f32, f32, f32), depth: &mut [f32]) {
        let (u, v) = (self.su * pu + self.half, self.sv * pv + self.half);
        // Bounds checked in floats, so the cast (the floor, for values
        // in [0, l)) needs no saturation handling.
        if CHECK && !((u >= 0.0) & (v >= 0.0) & (u < self.side) & (v < self.side)) {
            return;
        }
        let (u, v) = (u as i32 as usize, v as i32 as usize);
        let z = self.sd * pd;
        if let Some(cell) = depth.get_mut(v * self.l + u) {
            // A min, not a branch: which point is nearer is unpredictable.
            *cell = if z < *cell { z } else { *cell };
        }
    }

    fn splat<const U: usize, const V: usize, const D: usize>(
        &self,
        points: &[[f32; 3]],
        inside: bool,
        depth: &mut [f32],
    ) {
        if inside {
            for p in points {
                self.splat_one::<false>((p[U], p[V], p[D]), depth);
            }
        } else {
            for p in points {
                self.splat_one::<true>((p[U], p[V], p[D]), depth);
            }
        }
    }

    fn splat_any(&self, [ju, jv, jd]: [usize; 3], points: &[[f32; 3]], depth: &mut [f32]) {
        for p in points {
            self.splat_one::<true>((p[ju], p[jv], p[jd]), depth);
        }
    }
}

/// Inclusive pixel bounds of the filled pixels.
#[derive(Debug, Clone, Copy)]
struct PixelBox {
    u0: usize,
    u1: usize,
    v0: usize,
    v1: usize,
}

impl PixelBox {
    const EMPTY: Self = Self {
        u0: usize::MAX,
        u1: 0,
        v0: usize::MAX,
        v1: 0,
    };

    #[cfg(test)]
    fn include(&mut self, u: usize, v: usize) {
        (self.u0, self.u1, self.v0, self.v1) =
            (self.u0.min(u), self.u1.max(u), self.v0.min(v), self.v1.max(v));
    }
}

/// One order-independent pass of the hole rule documented above, over the
/// box of the filled pixels (nothing outside it can be filled), in place:
/// the unfilled rows above and at the current one are kept aside, the row
/// below is not written yet, so every decision reads the unfilled buffer.
fn fill_holes(depth: &mut [f32], l: usize, filled: &PixelBox) {
    if filled.u0 > filled.u1 || l < 3 {
        return;
    }
    let (u0, u1) = (filled.u0.max(1), filled.u1.min(l - 2));
    let (v0, v1) = (filled.v0.max(1), filled.v1.min(l - 2));
    if u0 > u1 || v0 > v1 {
        return;
    }
    let mut above = depth[(v0 - 1) * l..v0 * l].to_vec();
    let mut current = vec![0f32; l];
    for v in v0..=v1 {
        current.copy_from_slice(&depth[v * l..(v + 1) * l]);
        for u in u0..=u1 {
            if current[u].is_finite() {
                continue;
            }
            let below = &depth[(v + 1) * l..(v + 2) * l];
            let mut count = 0;
            let mut nearest = f32::INFINITY;
            for row in [&above[..], &current[..], below] {
                for &z in &row[u - 1..=u + 1] {
                    count += usize::from(z.is_finite());
                    nearest = nearest.min(z);
                }
            }
            if count >= HOLE_FILL_MIN_NEIGHBOURS {
                depth[v * l + u] = nearest;
            }
        }
        std::mem::swap(&mut above, &mut current);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_frames_are_right_handed() {
        for axis in ViewAxis::ALL {
            for plus_y in [false, true] {
                let m = axis.object_from_view(plus_y);
                assert!((m.determinant() - 1.0).abs() < 1e-12, "{axis:?}");
                assert!((m.transpose() * m - Matrix3::identity()).norm() < 1e-12);
            }
        }
    }

    #[test]
    fn top_view_of_a_plate_is_flat_at_its_height() {
        // A 5 x 5 cm plate 2 cm above the centroid, sampled every 1 mm.
        let points: Vec<[f32; 3]> = (0..2500)
            .map(|i| {
                [
                    ((i % 50) as f32 + 0.5) * 0.001 - 0.025,
                    ((i / 50) as f32 + 0.5) * 0.001 - 0.025,
                    0.02,
                ]
            })
            .collect();
        let view = OrthoView::render(ViewAxis::Top, true, &points, 32, 0.0025);
        assert!((view.entropy - crate::select::view_entropy(&view.image)).abs() < 1e-9);
        assert!(
            (view.entropy - (400f64).log2()).abs() < 1e-6,
            "400 equal pixels: log2(400) bits"
        );
        let filled: Vec<usize> = (0..32 * 32).filter(|&i| view.depth_m[i].is_finite()).collect();
        assert_eq!(filled.len(), 20 * 20);
        for &i in &filled {
            assert!((view.depth_m[i] + 0.02).abs() < 1e-6);
            // cube of 8 cm: (0.04 + 0.02) / 0.08
            assert!((view.image[i] - 0.75).abs() < 1e-6);
        }
    }

    /// The rule read literally: every decision on a copy of the unfilled buffer.
    fn fill_holes_reference(depth: &[f32], l: usize) -> Vec<f32> {
        let mut out = depth.to_vec();
        for v in 1..l - 1 {
            for u in 1..l - 1 {
                if depth[v * l + u].is_finite() {
                    continue;
                }
                let neighbours = (v - 1..=v + 1).flat_map(|y| (u - 1..=u + 1).map(move |x| depth[y * l + x]));
                let count = neighbours.clone().filter(|z| z.is_finite()).count();
                if count >= HOLE_FILL_MIN_NEIGHBOURS {
                    out[v * l + u] = neighbours.fold(f32::INFINITY, f32::min);
                }
            }
        }
        out
    }

    #[test]
    fn in_place_hole_filling_matches_the_rule_on_random_buffers() {
        let mut rng = crate::rng::SplitMix64::new(7);
        for density in [0.3, 0.6, 0.8, 0.95] {
            let l = 24;
            let depth: Vec<f32> = (0..l * l)
                .map(|_| {
                    if rng.next_f64() < density {
                        rng.next_f64() as f32
                    } else {
                        f32::INFINITY
                    }
                })
                .collect();
            let mut filled = PixelBox::EMPTY;
            for (i, z) in depth.iter().enumerate() {
                if z.is_finite() {
                    filled.include(i % l, i / l);
                }
            }
            let mut out = depth.clone();
            fill_holes(&mut out, l, &filled);
            let expected = fill_holes_reference(&depth, l);
            assert_eq!(out, expected, "density {density}");
            assert!(
                out.iter().filter(|z| z.is_finite()).count() > depth.iter().filter(|z| z.is_finite()).count()
            );
        }
    }

    #[test]
    fn holes_fill_only_when_surrounded() {
        let l = 5;
        let mut depth = vec![f32::INFINITY; l * l];
        for v in 1..4 {
            for u in 1..4 {
                depth[v * l + u] = 0.01 * (u + v) as f32;
            }
        }
        depth[2 * l + 2] = f32::INFINITY; // a one-pixel hole inside a 3x3 patch
        let mut filled = PixelBox::EMPTY;
        for v in 1..4 {
            for u in 1..4 {
                filled.include(u, v);
            }
        }
        let mut out = depth.clone();
        fill_holes(&mut out, l, &filled);
        assert_eq!(out[2 * l + 2], 0.02, "nearest of the 8 neighbours");
        assert!(
            out[0].is_infinite() && out[l].is_infinite(),
            "edges with < 5 neighbours stay empty"
        );
        assert_eq!(out.iter().filter(|z| z.is_finite()).count(), 9);
    }
}
