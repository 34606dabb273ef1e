//! Orthographic virtual views of each object.

mod orthographic;

pub use orthographic::{HOLE_FILL_MIN_NEIGHBOURS, OBLIQUE_TILT_DEG, OrthoView, ViewAxis};

/// Whether the pixel holding image point `(x, y)` (pixel units, origin at the
/// top-left corner) is inside an `l x l` view and shows the object.
fn filled(image: &[f32], l: usize, x: f64, y: f64) -> bool {
    let (xi, yi) = (x.floor(), y.floor());
    xi >= 0.0
        && yi >= 0.0
        && (xi as usize) < l
        && (yi as usize) < l
        && image[yi as usize * l + xi as usize] > 0.0
}

/// The silhouette's extent (px) through image point `(x, y)` along the unit
/// image direction `(c, s)`, both ways, bridging gaps of one pixel: the
/// opening a grasp there needs, in pixels.
pub fn silhouette_extent_px(image: &[f32], l: usize, x: f64, y: f64, c: f64, s: f64) -> f64 {
    let (ahead, behind) = silhouette_reach_px(image, l, x, y, c, s);
    ahead + behind + 1.0
}

/// How far the silhouette reaches from image point `(x, y)` along the unit
/// image direction `(c, s)` and against it (px, from the point), bridging
/// gaps of one pixel: the two halves of [`silhouette_extent_px`] less the
/// point's own pixel. 0 where nothing shows within 1.5 px.
pub fn silhouette_reach_px(image: &[f32], l: usize, x: f64, y: f64, c: f64, s: f64) -> (f64, f64) {
    let reach = |sign: f64| {
        let (mut t, mut last) = (0.0, 0.0);
        while t < l as f64 {
            t += 0.5;
            if filled(image, l, x + sign * t * c, y + sign * t * s) {
                last = t;
            } else if t - last > 1.5 {
                break;
            }
        }
        last
    };
    (reach(1.0), reach(-1.0))
}

/// The share of the disc of radius `r_px` around `(x, y)` that shows the object.
pub fn silhouette_share(image: &[f32], l: usize, x: f64, y: f64, r_px: isize) -> f32 {
    let (mut inside, mut lit) = (0, 0);
    for dy in -r_px..=r_px {
        for dx in -r_px..=r_px {
            if dx * dx + dy * dy <= r_px * r_px {
                inside += 1;
                lit += usize::from(filled(image, l, x + dx as f64, y + dy as f64));
            }
        }
    }
    lit as f32 / inside.max(1) as f32
}
