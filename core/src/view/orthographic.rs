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
//! | `TopFront` | between `Top` and `Front`, [`OBLIQUE_TILT_DEG`] off -Z | +Y | towards +X and down |
//! | `TopSide`  | between `Top` and `Side`, [`OBLIQUE_TILT_DEG`] off -Z | as `Side` | towards the camera's Y side and down |
//!
//! The oblique views' grasps approach from above, tilted towards the side the
//! camera saw: inside an approach cone about straight down that refuses
//! every `Front` and `Side` grasp.
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

/// How far the oblique views' direction leans from straight down (degrees).
pub const OBLIQUE_TILT_DEG: f64 = 45.0;

/// Which virtual camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ViewAxis {
    /// Looking down along -Z.
    Top,
    /// Looking along -X, at the side facing the camera.
    Front,
    /// Looking along +-Y, at the side facing the camera.
    Side,
    /// Looking down, leaning [`OBLIQUE_TILT_DEG`] towards `Front`.
    TopFront,
    /// Looking down, leaning [`OBLIQUE_TILT_DEG`] towards `Side`.
    TopSide,
}

impl ViewAxis {
    /// The paper's three views, in their canonical order.
    pub const ALL: [ViewAxis; 3] = [ViewAxis::Top, ViewAxis::Front, ViewAxis::Side];

    /// Every view the renderer knows: the paper's three, then the oblique two.
    pub const EVERY: [ViewAxis; 5] = [
        ViewAxis::Top,
        ViewAxis::Front,
        ViewAxis::Side,
        ViewAxis::TopFront,
        ViewAxis::TopSide,
    ];

    /// The view called `name` (as [`ViewAxis::name`] writes it).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::EVERY.into_iter().find(|a| a.name() == name)
    }

    /// Lower-case name, for logs and metrics.
    pub fn name(self) -> &'static str {
        match self {
            Self::Top => "top",
            Self::Front => "front",
            Self::Side => "side",
            Self::TopFront => "top_front",
            Self::TopSide => "top_side",
        }
    }

    /// Columns (u, v, viewing direction) in the object frame. `camera_on_plus_y`
    /// says which Y side the camera saw; only `Side` depends on it.
    pub fn object_from_view(self, camera_on_plus_y: bool) -> Matrix3<f64> {
        let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
        // The oblique views: `Front` or `Side` turned about their image u
        // axis until they look down, OBLIQUE_TILT_DEG off vertical.
        let (c, s) = (
            OBLIQUE_TILT_DEG.to_radians().cos(),
            OBLIQUE_TILT_DEG.to_radians().sin(),
        );
        let lean = |u: Vector3<f64>, towards: Vector3<f64>| {
            let d = -(towards * s + z * c);
            (u, d.cross(&u), d)
        };
        let (u, v, d) = match self {
            Self::Top => (x, -y, -z),
            Self::Front => (y, -z, -x),
            Self::Side if camera_on_plus_y => (-x, -z, -y),
            Self::Side => (x, -z, y),
            Self::TopFront => lean(y, x),
            Self::TopSide if camera_on_plus_y => lean(-x, y),
            Self::TopSide => lean(x, -y),
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
        let l = size_px;
        let mut depth = vec![f32::INFINITY; l * l];
        let splat = Splat {
            object_from_view: &object_from_view,
            points_in_object,
            extent,
            l,
            pixel_size_m,
        };
        let filled_box = if is_signed_permutation(&object_from_view) {
            splat_permuted(&splat, &mut depth)
        } else {
            splat_rotated(&splat, &mut depth)
        };
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

/// Whether every column of `m` is plus or minus one coordinate axis.
fn is_signed_permutation(m: &Matrix3<f64>) -> bool {
    m.iter().all(|&x| x == 0.0 || x.abs() == 1.0)
}

/// What a z-buffer splat draws: points (object frame) in their box, seen
/// through a view's axes into an `l x l` image of `pixel_size_m` pixels.
struct Splat<'a> {
    object_from_view: &'a Matrix3<f64>,
    points_in_object: &'a [[f32; 3]],
    extent: ([f32; 3], [f32; 3]),
    l: usize,
    pixel_size_m: f32,
}

/// The z-buffer splat of a view whose axes are signed object axes (the
/// paper's three): no matrix product. Returns the box of pixels a surface
/// can fill.
fn splat_permuted(splat: &Splat<'_>, depth: &mut [f32]) -> PixelBox {
    let &Splat {
        object_from_view,
        points_in_object,
        extent,
        l,
        pixel_size_m,
    } = splat;
    // Every view axis is +- one object axis: a signed permutation, no matrix product.
    let axis_of = |column: usize| {
        let c = object_from_view.column(column);
        let j = c.iamax();
        (j, c[j].signum() as f32)
    };
    let [(ju, su), (jv, sv), (jd, sd)] = [axis_of(0), axis_of(1), axis_of(2)];
    let inv = 1.0 / pixel_size_m;
    let half = l as f32 * 0.5;
    let (su, sv) = (su * inv, sv * inv);
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
        (0, 1, 2) => projection.splat::<0, 1, 2>(points_in_object, inside, depth),
        (1, 2, 0) => projection.splat::<1, 2, 0>(points_in_object, inside, depth),
        (0, 2, 1) => projection.splat::<0, 2, 1>(points_in_object, inside, depth),
        _ => projection.splat_any([ju, jv, jd], points_in_object, depth),
    }
    filled_box
}

/// The z-buffer splat of an oblique view: each point through the view's
/// rotation. Returns the box of pixels a surface can fill (the extent's
/// eight corners' pixels).
fn splat_rotated(splat: &Splat<'_>, depth: &mut [f32]) -> PixelBox {
    let l = splat.l;
    let inv = 1.0 / splat.pixel_size_m;
    let half = l as f32 * 0.5;
    let row = |c: usize, scale: f32| {
        let col = splat.object_from_view.column(c);
        [
            col[0] as f32 * scale,
            col[1] as f32 * scale,
            col[2] as f32 * scale,
        ]
    };
    let (ru, rv, rd) = (row(0, inv), row(1, inv), row(2, 1.0));
    let dot = |r: &[f32; 3], p: &[f32; 3]| r[0] * p[0] + r[1] * p[1] + r[2] * p[2];
    let side = l as f32;
    for p in splat.points_in_object {
        let (u, v) = (dot(&ru, p) + half, dot(&rv, p) + half);
        if !((u >= 0.0) & (v >= 0.0) & (u < side) & (v < side)) {
            continue;
        }
        let cell = &mut depth[(v as usize) * l + u as usize];
        let z = dot(&rd, p);
        *cell = if z < *cell { z } else { *cell };
    }
    let (lo, hi) = splat.extent;
    let (mut umin, mut umax, mut vmin, mut vmax) =
        (f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY);
    for corner in 0..8 {
        let p = [0, 1, 2].map(|a| if corner >> a & 1 == 1 { hi[a] } else { lo[a] });
        let (u, v) = (dot(&ru, &p) + half, dot(&rv, &p) + half);
        (umin, umax, vmin, vmax) = (umin.min(u), umax.max(u), vmin.min(v), vmax.max(v));
    }
    if splat.points_in_object.is_empty() || l == 0 || umax < 0.0 || vmax < 0.0 || umin >= side || vmin >= side
    {
        return PixelBox::EMPTY;
    }
    // One pixel of slack for the f32 products' rounding.
    let clamp = |x: f32| x.clamp(0.0, side - 1.0) as usize;
    PixelBox {
        u0: clamp(umin - 1.0),
        u1: clamp(umax + 1.0),
        v0: clamp(vmin - 1.0),
        v1: clamp(vmax + 1.0),
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
        for axis in ViewAxis::EVERY {
            for plus_y in [false, true] {
                let m = axis.object_from_view(plus_y);
                assert!((m.determinant() - 1.0).abs() < 1e-12, "{axis:?}");
                assert!((m.transpose() * m - Matrix3::identity()).norm() < 1e-12);
            }
        }
    }

    #[test]
    fn oblique_views_look_down_leaning_towards_the_camera_side() {
        let tilt = OBLIQUE_TILT_DEG.to_radians();
        for (axis, plus_y, towards) in [
            (ViewAxis::TopFront, true, Vector3::x()),
            (ViewAxis::TopFront, false, Vector3::x()),
            (ViewAxis::TopSide, true, Vector3::y()),
            (ViewAxis::TopSide, false, -Vector3::y()),
        ] {
            let m = axis.object_from_view(plus_y);
            let d = m.column(2).into_owned();
            assert!((d.dot(&-Vector3::z()) - tilt.cos()).abs() < 1e-12, "{axis:?}");
            assert!(
                (d.dot(&-towards) - tilt.sin()).abs() < 1e-12,
                "{axis:?} looks from {towards:?}"
            );
            assert!(m.column(0).z.abs() < 1e-12, "{axis:?}: image u stays horizontal");
            assert!(m.column(1).z < 0.0, "{axis:?}: image down is down");
            assert_eq!(ViewAxis::from_name(axis.name()), Some(axis));
        }
        assert_eq!(ViewAxis::from_name("diagonal"), None);
    }

    /// Points on the faces of a box, 1 mm apart, object frame.
    fn box_surface(half: [f32; 3]) -> Vec<[f32; 3]> {
        let mut points = Vec::new();
        let steps = half.map(|h| (2.0 * h / 0.001).round() as usize);
        for a in 0..3 {
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            for sign in [-1.0f32, 1.0] {
                for i in 0..=steps[b] {
                    for j in 0..=steps[c] {
                        let mut p = [0.0; 3];
                        p[a] = sign * half[a];
                        p[b] = -half[b] + i as f32 * 0.001;
                        p[c] = -half[c] + j as f32 * 0.001;
                        points.push(p);
                    }
                }
            }
        }
        points
    }

    #[test]
    fn the_rotated_splat_draws_the_paper_views_as_the_permuted_one() {
        let points = box_surface([0.03, 0.02, 0.045]);
        let extent = ([-0.03, -0.02, -0.045], [0.03, 0.02, 0.045]);
        let (l, s) = (48, 0.0025);
        for axis in ViewAxis::ALL {
            for plus_y in [false, true] {
                let m = axis.object_from_view(plus_y);
                let mut fast = vec![f32::INFINITY; l * l];
                let mut general = fast.clone();
                let splat = Splat {
                    object_from_view: &m,
                    points_in_object: &points,
                    extent,
                    l,
                    pixel_size_m: s,
                };
                let fast_box = splat_permuted(&splat, &mut fast);
                let general_box = splat_rotated(&splat, &mut general);
                let filled = |d: &[f32]| d.iter().filter(|z| z.is_finite()).count();
                assert!(filled(&fast) > 100, "{axis:?}");
                // Rounding may move a point on a pixel's edge: nearly every pixel agrees.
                let differ = fast
                    .iter()
                    .zip(&general)
                    .filter(|(a, b)| (*a - *b).abs() > 1e-6)
                    .count();
                assert!(differ * 50 < filled(&fast), "{axis:?}: {differ} pixels differ");
                assert!(
                    general_box.u0 <= fast_box.u0
                        && general_box.u1 >= fast_box.u1
                        && general_box.v0 <= fast_box.v0
                        && general_box.v1 >= fast_box.v1,
                    "{axis:?}: the corners' box holds every surface"
                );
            }
        }
    }

    #[test]
    fn an_oblique_view_of_a_box_sees_its_top_and_its_camera_side() {
        // A 6 x 4 x 9 cm box (x, y, z), camera on +x: `TopFront` sees the
        // top (6 cm deep, foreshortened by cos 45) above the +x face (9 cm
        // high, by sin 45), 4 cm wide.
        let half = [0.03f32, 0.02, 0.045];
        let points = box_surface(half);
        let (l, s) = (72, 0.0025);
        let view = OrthoView::render(ViewAxis::TopFront, true, &points, l, s);
        let d = view.object_from_view.column(2).into_owned();
        let rows: Vec<usize> = (0..l)
            .filter(|&v| (0..l).any(|u| view.depth_m[v * l + u].is_finite()))
            .collect();
        let c = std::f64::consts::FRAC_1_SQRT_2;
        let expected_rows = (0.06 * c + 0.09 * c) / f64::from(s);
        assert!(
            (rows.len() as f64 - expected_rows).abs() <= 2.0,
            "{} rows, expected {expected_rows:.1}",
            rows.len()
        );
        // Each filled pixel holds the nearest face: no hidden (-x or
        // bottom) face shows through.
        for v in 0..l {
            for u in 0..l {
                let z = view.depth_m[v * l + u];
                if z.is_finite() {
                    let p = view.point_in_object(u as f64 + 0.5, v as f64 + 0.5, f64::from(z));
                    let on_top = (p.z - 0.045).abs() < 0.003;
                    let on_front = (p.x - 0.03).abs() < 0.003;
                    assert!(on_top || on_front, "pixel {u},{v} shows {p:?} (d = {d:?})");
                }
            }
        }
        assert!(view.entropy > 0.0);
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
